"""data=recordings end to end, on recordings written by an independent simulation (tests/helpers/recordings.py:
the seat equation solved by scipy's solve_ivp): a label-free run on the files lands as close to the truth as the
same run on the simulator's own data, and the errors-in-variables estimator on the files gives the fit computed
here."""

import hashlib

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.training.run import train

from helpers.recordings import seat_recordings, write_folder, write_labels

DT = 0.005


def run(run_dir, overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[*overrides, "trainer.progress_bar=false"])
    return train(cfg, run_dir, overrides)


def test_a_label_free_run_on_files_lands_as_close_to_the_truth_as_on_the_simulators_data(tmp_path, tiny_cache):
    """48 recordings of 400 steps (data=tiny's count and length), 24 in CSV files and 24 in one .npz, trained
    label-free (objective=hybrid, 150 steps) without labels, and the same run on data=tiny with the continuous
    measurement. Measured: files 10.3% / 9.7% (p1 / p2) against the truth, simulator 15.3% / 15.7%; over four
    sets of files (seeds 0-3) the files' error was 0.42-0.78 of the simulator's. Allowed: 1.5 of it."""
    seat, body, p, _ = seat_recordings(48, 400, DT, seed=0)
    names = write_folder(tmp_path / "files", seat, body, DT, npz_from=24)
    truth = dict(zip(names, map(tuple, p)))
    common = ["objective=hybrid", "trainer=debug", "trainer.max_steps=150", "trainer.eval_every_n_steps=75"]
    common += ["data.window=200", "data.val_fraction=0.25"]
    record = run(tmp_path / "files_run", ["data=recordings", f"data.path={tmp_path / 'files'}", *common])
    sim = run(
        tmp_path / "sim_run", ["data=tiny", "data.measurement=continuous", f"data.cache_dir={tiny_cache}", *common]
    )

    predictions = pd.read_csv(tmp_path / "files_run" / "predictions.csv", converters={"recording": str})
    test = predictions[(predictions.split == "test") & (predictions.noise_std == 0)]
    assert set(test.recording) <= set(names) and len(test) == 10  # every recording by its name, 10 of 48 test
    true = np.array([truth[r] for r in test.recording])
    files_error = np.abs(test[["p1_pred", "p2_pred"]].to_numpy() / true - 1).mean(axis=0)
    # without labels the reference is the errors-in-variables fit of each whole recording: on clean recordings
    # of the seat equation it is the truth (5e-8 measured; float32 channels)
    np.testing.assert_allclose(test[["p1_true", "p2_true"]].to_numpy(), true, rtol=1e-5)
    rows = [r for r in record["results"] if r["split"] == "test"]
    assert rows and all(r["reference"] == "fit over the whole recording" for r in rows)
    assert record["reference"] == "fit over the whole recording"
    sim_error = np.array(
        [
            next(r["mean_rel_dev"] for r in sim["results"] if (r["split"], r["noise_std"], r["parameter"]) == key)
            for key in (("test", 0.0, "p1"), ("test", 0.0, "p2"))
        ]
    )
    assert (files_error < 0.2).all(), files_error  # it learned: a constant guess is about 30% off
    assert (files_error <= 1.5 * sim_error).all(), (files_error, sim_error)


@pytest.fixture
def window_long(tmp_path):
    """12 recordings exactly data.window = 200 steps long (so each test window is the whole recording), in CSV."""
    seat, body, p, _ = seat_recordings(12, 200, DT, seed=3)
    names = write_folder(tmp_path / "files", seat, body, DT)
    return tmp_path / "files", names, seat, body, p


def test_the_eiv_estimator_on_files_gives_the_fit_computed_here(tmp_path, window_long):
    """estimator=eiv on recordings one window long: each test estimate is the errors-in-variables fit of the whole
    recording, computed here from the float32 samples the run reads, and so is the reference (deviation 0). The
    record names its files with their sizes and sha256, and the bound at added noise."""
    folder, names, seat, body, p = window_long
    args = ["data=recordings", f"data.path={folder}", "data.window=200", "estimator=eiv", "noise.eval_std=[0.0,0.01]"]
    record = run(tmp_path / "run", args)
    predictions = pd.read_csv(tmp_path / "run" / "predictions.csv", converters={"recording": str})
    test = predictions[(predictions.split == "test") & (predictions.noise_std == 0)]
    index = [names.index(r) for r in test.recording]
    x32 = [x[index].astype(np.float32).astype(np.float64) for x in (seat, body)]
    expected = ErrorsInVariablesFit(dt=DT).fit(*x32, DT, "continuous")
    np.testing.assert_allclose(test[["p1_pred", "p2_pred"]].to_numpy(), expected, rtol=1e-9)
    np.testing.assert_allclose(test[["p1_true", "p2_true"]].to_numpy(), expected, rtol=1e-6)  # float32 labels
    np.testing.assert_allclose(expected, p[index], rtol=1e-6)  # the fit of a clean recording is the truth
    clean = [r for r in record["results"] if r["split"] == "test" and r["noise_std"] == 0]
    assert all(r["mean_rel_dev"] < 1e-6 for r in clean)
    noisy = [r for r in record["results"] if r["split"] == "test" and r["noise_std"] == 0.01]
    assert all(r["bound"] > 0 and r["mean_rel_dev"] > 0 for r in noisy)
    files = {f["name"]: f for f in record["data_files"]["files"]}
    assert sorted(files) == sorted(f"{n}.csv" for n in names) and record["data_files"]["recordings"] == 12
    for name, f in files.items():
        data = (folder / name).read_bytes()
        assert f["bytes"] == len(data) and f["sha256"] == hashlib.sha256(data).hexdigest()
    assert all(set(f) == {"name", "bytes", "sha256"} for f in files.values())  # a fingerprint, never the samples


def test_a_labelled_run_on_files_scores_eq_24_against_the_labels(tmp_path, window_long):
    """Labels as c3, k3 and m3: a labelled objective trains on them, and each test row is eq. 24 against
    p = (c3, k3) / m3, computed here from the truth the files were simulated with."""
    folder, names, _, _, p = window_long
    m3 = 615.0 / p[:, 0]
    labels = write_labels(tmp_path / "labels.csv", names, p, m3, form="c3k3m3")
    args = ["data=recordings", f"data.path={folder}", f"data.labels={labels}", "data.window=200"]
    record = run(tmp_path / "run", [*args, "objective=labelled", "trainer=debug", "trainer.max_steps=10"])
    predictions = pd.read_csv(tmp_path / "run" / "predictions.csv", converters={"recording": str})
    test = predictions[(predictions.split == "test") & (predictions.noise_std == 0)]
    index = [names.index(r) for r in test.recording]
    np.testing.assert_allclose(test[["p1_true", "p2_true"]].to_numpy(), p[index], rtol=1e-6)  # float32 labels
    np.testing.assert_allclose(test.m3.to_numpy(), m3[index], rtol=1e-12)
    deviation = np.abs(test[["p1_pred", "p2_pred"]].to_numpy() / p[index] - 1).mean(axis=0)
    rows = {r["parameter"]: r for r in record["results"] if r["split"] == "test" and r["noise_std"] == 0}
    np.testing.assert_allclose([rows["p1"]["mean_rel_dev"], rows["p2"]["mean_rel_dev"]], deviation, rtol=1e-5)
    assert record["reference"] == "labels" and all(r["reference"] == "labels" for r in rows.values())
    data = labels.read_bytes()
    assert record["data_files"]["labels"] == {
        "name": "labels.csv",
        "bytes": len(data),
        "sha256": hashlib.sha256(data).hexdigest(),
    }


def test_cross_segment_trains_on_recordings_of_several_lengths(tmp_path):
    """objective=cross_segment reads each window's outside samples: on files of 900 and 1,100 steps it trains
    without labels and tests recordings of both lengths, each against the fit of its own whole recording (the
    truth here). tests/data/test_outside_fit.py checks each row's outside fit against the unpadded recording's."""
    short = seat_recordings(16, 900, DT, seed=5)
    long = seat_recordings(16, 1100, DT, seed=6)
    folder = tmp_path / "files"
    names = write_folder(folder, short[0], short[1], DT)  # rec000.csv ..., and the longer ones in one .npz
    np.savez(folder / "long.npz", seat_acc=long[0], body_acc=long[1], dt=DT)
    truth = dict(zip(names + [f"long:{i}" for i in range(16)], map(tuple, np.concatenate([short[2], long[2]]))))
    overrides = ["data=recordings", f"data.path={folder}", "objective=cross_segment", "trainer=debug"]
    overrides += ["trainer.max_steps=60", "trainer.eval_every_n_steps=30", "data.window=200"]
    overrides += ["data.val_fraction=0.25"]
    record = run(tmp_path / "run", overrides)
    assert record["status"] == "completed" and record["reference"] == "fit over the whole recording"
    predictions = pd.read_csv(tmp_path / "run" / "predictions.csv", converters={"recording": str})
    test = predictions[(predictions.split == "test") & (predictions.noise_std == 0)]
    assert {r.startswith("long:") for r in test.recording} == {True, False}  # both lengths reach the test split
    np.testing.assert_allclose(test[["p1_true", "p2_true"]].to_numpy(), [truth[r] for r in test.recording], rtol=1e-5)
