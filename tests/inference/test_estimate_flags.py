"""When not to trust an estimate (docs/predict.md, "Flags"): estimates outside the trained range or at the network's
output bound, swapped or mis-scaled channels, a run whose own test error is large; and least-squares baseline runs,
which estimate recordings too. Every expectation comes from the simulator's truth or from the test's own numbers."""

import io
import json
import re
import shutil
import warnings

import numpy as np
import pandas as pd
import pytest
import torch
from omegaconf import OmegaConf

from hybrid_sysid.inference.estimator import Estimator
from hybrid_sysid.inference.inputs import EstimateWarning, InputError
from hybrid_sysid.model.networks import FastCNN
from hybrid_sysid.physics import road_profiles, simulate

from helpers.estimator_run import (  # the trained run's fixtures, tiny_run and est, come with it
    C3,
    K3,
    TINY,
    predict,
    recordings,
)

M3_MIN, M3_MAX = 50.0, 200.0  # data=tiny's seat masses (data/default.yaml)
P_MIN, P_MAX = np.array([C3, K3]) / M3_MAX, np.array([C3, K3]) / M3_MIN
CLEAN = {"split": "test", "noise_std": 0.0}


def quiet_predict(est, *args, **kwargs):
    """est.predict with its EstimateWarnings caught: (table, warning messages)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", EstimateWarning)
        table = est.predict(*args, **kwargs)
    return table, [str(w.message) for w in caught if w.category is EstimateWarning]


def flagged(table, code):
    return np.array([code in f.split(",") for f in table.flag])


def record(**errors):
    """A metrics.json of clean test rows: errors as {f"k{K}": (p1, p2)}."""
    rows = []
    for key, pair in errors.items():
        for parameter, value in zip(("p1", "p2"), pair):
            rows.append({**CLEAN, "windows": int(key[1:]), "parameter": parameter, "mean_rel_dev": value})
    return {"status": "completed", "results": rows}


def heavy(m3, n, dt, n_steps=400):
    """n recordings of one seat mass m3 (kg) on roads of every class, simulated like the run's data."""
    road = road_profiles(("ABCDE" * n)[:n], n_steps, dt, 15.0, rng=3)
    return simulate(road, np.full(n, float(m3)), dt, measurement="consistent")


def test_swapped_or_misscaled_channels_are_flagged(est):
    """Swapped seat and body invert the seat's amplification around its resonance; one channel in other units
    (x 9.81: g read as m/s^2 twice) or both in mm/s^2 leave the simulated range. Unchanged recordings from the
    run's distribution are not flagged."""
    n = 12
    seat, body, _ = recordings(n, 400, est.dt, seed=21)
    plain, _ = quiet_predict(est, seat, body, est.dt)
    assert not flagged(plain, "channels").any(), plain.flag
    for what, s, b in (
        ("swapped", body, seat),
        ("seat x 9.81", seat * 9.81, body),
        ("body x 9.81", seat, body * 9.81),
        ("mm/s^2", seat * 1000, body * 1000),
    ):
        table, lines = quiet_predict(est, s, b, est.dt)
        assert flagged(table, "channels").all(), (what, table.flag)
        assert sum(f"{n} of {n} recordings" in x and "flag channels" in x for x in lines) == 1, (what, lines)


def test_a_seat_mass_far_outside_the_trained_range_is_flagged(est):
    """1000 kg, five times the heaviest trained seat: the network saturates near its upper bound (230 kg); masses
    well inside the range (90 to 130 kg) are not flagged."""
    table, lines = quiet_predict(est, *heavy(1000, 5, est.dt), est.dt)
    assert flagged(table, "range").all(), table[["m3_from_p1", "flag"]]
    assert any("5 of 5 recordings" in x and "may lie beyond the range" in x for x in lines), lines
    road = road_profiles("ABCDEABCDE", 400, est.dt, 15.0, rng=4)
    seat, body = simulate(road, np.linspace(90, 130, 10), est.dt, measurement="consistent")
    table, lines = quiet_predict(est, seat, body, est.dt)
    assert not flagged(table, "range").any(), table[["m3_from_p1", "flag"]]
    assert not any("trained range" in x for x in lines)


@pytest.mark.parametrize("bias, flag", [(30.0, True), (-30.0, True), (0.0, False)], ids=["top", "bottom", "middle"])
def test_an_estimate_at_the_networks_bound_is_flagged_even_inside_the_range(est, bias, flag):
    """A head without margin saturates exactly at the edges of the trained range: an estimate there is flagged
    (the true mass may lie beyond); the middle of the range is not."""
    net = FastCNN(P_MIN.tolist(), P_MAX.tolist(), margin=0.0)
    with torch.no_grad():
        net.head.weight.zero_()
        net.head.bias.fill_(bias)
    seat, body, _ = recordings(3, 400, est.dt)
    table, _ = quiet_predict(Estimator(net, est.config, record=record(k1=(0.01, 0.01))), seat, body, est.dt)
    p = table[["p1", "p2"]].to_numpy()
    if flag:  # at an edge of the range, inside it or beyond by float32 rounding only
        assert np.abs(p / (P_MAX if bias > 0 else P_MIN) - 1).max() < 1e-5
    assert (flagged(table, "range") == flag).all(), table


def test_a_run_with_a_large_or_unknown_test_error_flags_every_estimate(est):
    seat, body, _ = recordings(2, 400, est.dt)
    cases = [
        (record(k1=(0.40, 0.38)), 8, True, "clean test error is 40.0% mean relative deviation (K = 1"),
        (record(k1=(0.02, 0.03)), 8, False, None),
        (None, 8, True, "test error is unknown"),
        (record(k1=(-0.5, -0.5)), 8, True, "test error is unknown"),  # impossible: no measurement
        (record(k1=(float("inf"), 0.01)), 8, True, "test error is unknown"),
        # the record's K nearest below the prediction's: K = 8 rows for windows=8, K = 1 for windows=4
        (record(k1=(0.20, 0.20), k8=(0.05, 0.04)), 8, False, None),
        (record(k1=(0.20, 0.20), k8=(0.05, 0.04)), 4, True, "is 20.0% mean relative deviation (K = 1"),
    ]
    for rec, k, flag, message in cases:
        table, lines = quiet_predict(Estimator(est.net, est.config, record=rec), seat, body, est.dt, windows=k)
        assert (flagged(table, "run_error") == flag).all(), (rec, table.flag)
        got = [x for x in lines if "flag run_error" in x]
        assert len(got) == int(flag) and (not flag or message in got[0]), (rec, lines)
        assert all(x.startswith("about the run, not these recordings: ") for x in got), got


@pytest.fixture(scope="module")
def baseline_runs(tmp_path_factory, tiny_cache):
    """Least-squares baseline runs on data=tiny (no network: seconds), their configs saved as Hydra would."""
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.training.run import train

    runs = {}
    for name in ("ls_bandpass", "ls_window"):
        run_dir = tmp_path_factory.mktemp(name)
        overrides = [*TINY, f"baseline={name}", f"data.cache_dir={tiny_cache}"]
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            cfg = compose(config_name="config", overrides=overrides)
        train(cfg, run_dir, overrides)
        (run_dir / ".hydra").mkdir(exist_ok=True)
        OmegaConf.save(cfg, run_dir / ".hydra" / "config.yaml")
        runs[name] = run_dir
    return runs


def test_a_baseline_run_estimates_the_simulators_truth(baseline_runs):
    """ls_bandpass (one fit of each whole recording) and ls_window (K windows) are exact on clean, consistent
    recordings: the seat equation holds to rounding there (the largest deviation measured: 1.5e-12)."""
    from hybrid_sysid import load_estimator

    for name, windows in (("ls_bandpass", 1), ("ls_window", 8)):
        est = load_estimator(baseline_runs[name])
        assert est.net is None and est.baseline is not None
        for n_steps in (400, 1000):
            seat, body, p = recordings(6, n_steps, est.dt, seed=5)
            table, lines = quiet_predict(est, seat, body, est.dt)
            assert table[["p1", "p2"]].to_numpy() == pytest.approx(p, rel=1e-9), name
            assert table.m3_from_p1.to_numpy() == pytest.approx(C3 / p[:, 0], rel=1e-9)
            assert (table.windows == windows).all() and (table.flag == "").all() and lines == [], (name, lines)
        with pytest.raises(
            InputError,
            match=r"recording 0 is not allowed: accelerations of a car on a road: the least-squares fit of the run's "
            r"baseline",
        ):
            est.predict(np.zeros(400), np.zeros(400), est.dt)


def test_a_baseline_run_refuses_a_planted_target(baseline_runs, tmp_path):
    from hybrid_sysid import load_estimator

    run = tmp_path / "received"
    shutil.copytree(baseline_runs["ls_bandpass"], run)
    cfg = OmegaConf.load(run / ".hydra" / "config.yaml")
    cfg.baseline._target_ = "os.system"
    OmegaConf.save(cfg, run / ".hydra" / "config.yaml")
    with pytest.raises(InputError, match=r"baseline._target_ = 'os.system' is not allowed"):
        load_estimator(run)


def test_the_command_prints_the_flag_column_and_one_warning_per_kind(tiny_run, est, tmp_path, capsys):
    """A copy of the run whose record says 41% error at K = 8 (the command's K); three recordings: plain
    (100 kg), swapped (100 kg), heavy (1000 kg). The table's flag column marks each; stderr holds one line per
    kind, naming the recordings."""
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, ignore=shutil.ignore_patterns("figures", "*.csv"))
    (run / "metrics.json").write_text(json.dumps(record(k1=(0.40, 0.38), k8=(0.41, 0.39))))
    road = road_profiles("CDE", 400, est.dt, 15.0, rng=9)
    seat, body = simulate(road, np.array([100.0, 100.0, 1000.0]), est.dt, measurement="consistent")
    seat[1], body[1] = body[1].copy(), seat[1].copy()
    names = ["plain", "swapped", "heavy"]
    frames = [pd.DataFrame({"recording": m, "seat_acc": s, "body_acc": b}) for m, s, b in zip(names, seat, body)]
    pd.concat(frames).to_csv(tmp_path / "rec.csv", index=False)
    code, out, err = predict(capsys, f"run={run}", f"input={tmp_path / 'rec.csv'}", f"dt={est.dt}")
    assert code == 0, err
    assert out.splitlines()[0].split()[-1] == "flag"
    table = pd.read_csv(io.StringIO(out), sep=r"\s+")
    flags = dict(zip(table.recording, table.flag))
    assert flags["plain"] == "run_error"
    assert "channels" in flags["swapped"].split(",") and "range" in flags["heavy"].split(","), flags
    lines = err.splitlines()
    assert len(lines) == 3 and all(x.startswith("hybrid-sysid-predict: warning: ") for x in lines), lines
    kinds = {re.search(r"\(flag (\w+)", x).group(1): x for x in lines}
    assert set(kinds) == {"range", "channels", "run_error"}, lines
    assert "heavy" in kinds["range"] and "plain" not in kinds["range"]
    assert "swapped" in kinds["channels"] and "plain" not in kinds["channels"]
    assert "41.0% mean relative deviation (K = 8" in kinds["run_error"] and "on all 3" in kinds["run_error"]


def test_the_command_estimates_with_a_baseline_run(baseline_runs, tmp_path, capsys):
    seat, body, p = recordings(3, 500, 0.005, seed=8)
    np.savez(tmp_path / "rec.npz", seat_acc=seat, body_acc=body, dt=0.005)
    out = tmp_path / "out.csv"
    code, _, err = predict(
        capsys, f"run={baseline_runs['ls_bandpass']}", f"input={tmp_path / 'rec.npz'}", f"output={out}"
    )
    assert code == 0 and err == "", err
    got = pd.read_csv(out)
    assert got[["p1", "p2"]].to_numpy() == pytest.approx(p, rel=1e-9)
