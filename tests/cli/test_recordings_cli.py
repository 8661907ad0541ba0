"""data=recordings through the commands: a bad file is one line naming it (exit 2, no directory), a labelled
objective or monitor without labels is refused before any work, and a run on recordings is served by
hybrid-sysid-eval, hybrid-sysid-predict, load_estimator and init_from like any other, each recording by its name."""

import json

import numpy as np
import pandas as pd
import pytest

from helpers.estimator_run import predict, trained_run
from helpers.recordings import seat_recordings, write_folder, write_labels

DT = 0.005
BASE = ["data=recordings", "data.window=200", "objective=hybrid", "trainer=debug"]


def one_csv(path, seat, body, names, dt=DT):
    """Several recordings in one CSV file, a recording column naming each."""
    frames = [
        pd.DataFrame({"recording": n, "time": dt * np.arange(len(s)), "seat_acc": s, "body_acc": b})
        for n, s, b in zip(names, seat, body)
    ]
    pd.concat(frames).to_csv(path, index=False)


def bad_short(folder):
    seat, body, *_ = seat_recordings(1, 150, DT, seed=2)
    write_folder(folder / "x", seat, body)
    (folder / "x" / "rec000.csv").rename(folder / "short.csv")
    return "data.path = {folder}/short.csv: recording 'short' = 150 steps is not allowed: at least 200 steps"


def bad_mixed_dt(folder):
    seat, body, *_ = seat_recordings(1, 300, 0.004, seed=2)
    pd.DataFrame({"time": 0.004 * np.arange(300), "seat_acc": seat[0], "body_acc": body[0]}).to_csv(
        folder / "zz.csv", index=False
    )
    return "data.path = {folder}/zz.csv: its time step = 0.004 s is not allowed: one sample rate across data.path"


def bad_nan(folder):
    text = (folder / "rec001.csv").read_text().splitlines()
    cells = text[8].split(",")
    text[8] = ",".join([cells[0], "", cells[2]])  # an empty seat_acc cell in data row 8: step 7 (from 0)
    (folder / "rec001.csv").write_text("\n".join(text) + "\n")
    return "data.path = {folder}/rec001.csv: recording 'rec001', seat_acc = nan at step 7 (1 non-finite in all) is"


def bad_label(folder):
    names = [f"rec{i:03d}" for i in range(8)] + ["ghost"]
    write_labels(folder.parent / "labels.csv", names, np.full((9, 2), 5.0))
    return "data.labels = {folder}/../labels.csv: recording 'ghost' in data row 9 = a name data.path does not hold"


def bad_empty(folder):
    for f in folder.iterdir():
        f.unlink()
    (folder / "README.txt").write_text("no recordings here\n")
    return "data.path = {folder} is not allowed: a folder holding recordings, .csv or .npz files (it holds none)"


def bad_duplicate(folder):
    seat, body, *_ = seat_recordings(1, 240, DT, seed=2)
    np.savez(folder / "rec003.npz", seat_acc=seat[0], body_acc=body[0], dt=DT)
    return "data.path = {folder}/rec003.npz: recording 'rec003' = also in rec003.csv is not allowed: names unique"


def bad_text(folder):
    text = (folder / "rec002.csv").read_text().splitlines()
    cells = text[3].split(",")
    text[3] = ",".join([cells[0], cells[1], "abc"])
    (folder / "rec002.csv").write_text("\n".join(text) + "\n")
    return "data.path = {folder}/rec002.csv: column body_acc in data row 3 = 'abc' is not allowed: numbers"


def bad_dt(folder):
    return "data.dt = 0.002 is not allowed: the step of data.path's files, 0.005 s (data.dt=0.005)"


CASES = {
    "short": (bad_short, []),
    "mixed_dt": (bad_mixed_dt, []),
    "nan": (bad_nan, []),
    "label": (bad_label, ["data.labels={folder}/../labels.csv"]),
    "empty": (bad_empty, []),
    "duplicate": (bad_duplicate, []),
    "text": (bad_text, []),
    "dt": (bad_dt, ["data.dt=0.002"]),
    "labelled": (None, ["objective=labelled"]),
    "monitor": (None, ["trainer.monitor=val/rel_dev"]),
}
EXPECTED = {
    "labelled": "objective = hybrid_sysid.model.objectives.LabelledObjective is not allowed: an objective that reads",
    "monitor": "trainer.monitor = 'val/rel_dev' is not allowed: auto or val/loss, since data.labels is null",
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_bad_file_or_a_labelled_choice_without_labels_is_one_line_and_makes_nothing(tmp_path, cli_in_process, case):
    from hybrid_sysid.cli.train import main

    folder = tmp_path / "files"
    seat, body, *_ = seat_recordings(8, 240, DT, seed=1)
    write_folder(folder, seat, body)
    make, extra = CASES[case]
    expected = (make(folder) if make else EXPECTED[case]).format(folder=folder)
    run_dir = tmp_path / "run"
    args = [*BASE, f"data.path={folder}", *(a.format(folder=folder) for a in extra), f"hydra.run.dir={run_dir}"]
    code, out, err = cli_in_process(main, *args, cwd=tmp_path)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err[-2000:]
    assert lines[0].startswith(f"error: {expected}"), lines[0]
    assert not run_dir.exists() and not (tmp_path / "outputs").exists()


@pytest.fixture(scope="module")
def recordings_run(tmp_path_factory):
    """A label-free run (20 steps) on 12 recordings exactly one window long, all in one CSV file with a recording
    column: each test window is then the whole recording, so every command reads the run's very windows."""
    root = tmp_path_factory.mktemp("recordings_run")
    seat, body, p, _ = seat_recordings(12, 200, DT, seed=4)
    names = [f"drive-{i:02d}" for i in range(12)]
    one_csv(root / "drives.csv", seat, body, names)
    run = trained_run(
        root / "run", [*BASE, f"data.path={root / 'drives.csv'}", "trainer.max_steps=20", "trainer.progress_bar=false"]
    )
    return run, root / "drives.csv", names, seat, body


def test_eval_of_a_recordings_run_reads_files_only_when_named_and_keeps_their_names(recordings_run, cli_in_process):
    from hybrid_sysid.cli.evaluate import main

    run, csv, names, *_ = recordings_run
    out_dir = run.parent / "eval_unnamed"
    code, _, err = cli_in_process(main, f"run={run}", f"hydra.run.dir={out_dir}", cwd=run.parent)
    assert code == 2 and err.strip().startswith("error: data.path is missing: the recordings to evaluate on"), err
    assert not out_dir.exists()

    out_dir = run.parent / "eval"
    code, _, err = cli_in_process(main, f"run={run}", f"data.path={csv}", f"hydra.run.dir={out_dir}", cwd=run.parent)
    assert code == 0, err[-2000:]
    mine = pd.read_csv(run / "predictions.csv", converters={"recording": str})
    evaluated = pd.read_csv(out_dir / "predictions.csv", converters={"recording": str})
    assert set(evaluated.recording) == set(names)
    key = ["split", "noise_std", "windows", "recording"]
    both = mine.merge(evaluated, on=key, suffixes=("", "_eval"))
    assert len(both) == len(mine)  # the same split: data.seed splits alike
    np.testing.assert_allclose(both[["p1_pred_eval", "p2_pred_eval"]], both[["p1_pred", "p2_pred"]], rtol=1e-6)
    record = json.loads((out_dir / "metrics.json").read_text())
    assert record["reference"] == "fit over the whole recording" and record["source_run"] == str(run)


def test_predict_and_load_estimator_give_the_runs_own_estimates(recordings_run, tmp_path, capsys):
    from hybrid_sysid import load_estimator

    run, csv, names, seat, body = recordings_run
    mine = pd.read_csv(run / "predictions.csv", converters={"recording": str})
    test = mine[(mine.split == "test") & (mine.noise_std == 0)].set_index("recording")
    out = tmp_path / "estimates.csv"
    code, _, err = predict(capsys, f"run={run}", f"input={csv}", "windows=1", f"output={out}")
    assert code == 0, err
    table = pd.read_csv(out, converters={"recording": str}).set_index("recording")
    np.testing.assert_allclose(table.loc[test.index, ["p1", "p2"]], test[["p1_pred", "p2_pred"]], rtol=1e-5)
    est = load_estimator(run)
    rows = [names.index(n) for n in test.index]
    api = est.predict(seat[rows], body[rows], dt=DT, windows=1, names=list(test.index))
    np.testing.assert_allclose(api[["p1", "p2"]].to_numpy(), test[["p1_pred", "p2_pred"]].to_numpy(), rtol=1e-5)


@pytest.mark.parametrize("source", ["recordings", "simulated"])
def test_init_from_starts_a_recordings_run_from_a_run_on_recordings_or_on_simulations(
    recordings_run, tiny_run, tmp_path, cli_in_process, source
):
    """Adapting without labels: a network trained on simulations (or on recordings) continues on the files."""
    from hybrid_sysid.cli.train import main

    run, csv, *_ = recordings_run
    init = run if source == "recordings" else tiny_run
    args = [*BASE, f"data.path={csv}", f"init_from={init}", "trainer.max_steps=2", f"hydra.run.dir={tmp_path / 'r'}"]
    code, _, err = cli_in_process(main, *args, cwd=tmp_path)
    assert code == 0, err[-2000:]
    record = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert record["status"] == "completed" and record["init_from"] == str(init)
