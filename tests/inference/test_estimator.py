"""load_estimator / Estimator.predict: a trained run estimates recordings as training evaluated it; K windows,
resampling, the run's car, and bad input."""

import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf
from scipy.optimize import curve_fit

from hybrid_sysid.config import ConfigError
from hybrid_sysid.inference.estimator import resample_to
from hybrid_sysid.inference.inputs import InputError
from hybrid_sysid.model.metrics import relative_deviation

from helpers.estimator_run import C3, K3, recordings  # the trained run's fixtures, tiny_run and est, come with it
from helpers.started_early import started_early


def test_predicts_what_training_evaluated(tiny_run, est):
    """One window of a test recording gives the prediction train() wrote for it (its own evaluation path:
    the data module's batch, the best checkpoint), so channels, dtype, scaling and mode all match."""
    from hybrid_sysid.training.build import build_datamodule

    dm = build_datamodule(est.config)
    batch = dm.eval_batch("test")
    written = pd.read_csv(tiny_run / "predictions.csv").query("split == 'test' and noise_std == 0")
    seat_all, body_all = dm.dataset.seat_acc, dm.dataset.body_acc
    w = est.window
    for row, window in zip(batch["index"].numpy()[:6], batch["signals"][:6, 0].numpy()):
        views = np.lib.stride_tricks.sliding_window_view(seat_all[row], w)
        (start,) = np.flatnonzero((views == window).all(axis=1))
        got = est.predict(seat_all[row, start : start + w], body_all[row, start : start + w], est.dt, windows=1)
        want = written[written.recording == row].iloc[0]
        assert got.p1.item() == pytest.approx(want.p1_pred, rel=1e-5)
        assert got.p2.item() == pytest.approx(want.p2_pred, rel=1e-5)


def test_k_windows_evenly_spaced_mean_and_std(est):
    w = est.window
    seat, body, _ = recordings(1, w + 60, est.dt)
    got = est.predict(seat[0], body[0], est.dt, windows=3).iloc[0]
    singles = pd.concat([est.predict(seat[0, s : s + w], body[0, s : s + w], est.dt, windows=1) for s in (0, 30, 60)])
    for p in ("p1", "p2"):
        assert got[p] == pytest.approx(singles[p].mean(), rel=1e-6)
        assert got[f"{p}_std"] == pytest.approx(singles[p].std(ddof=0), rel=1e-5)
    assert got.m3_from_p1 == pytest.approx(C3 / got.p1) and got.m3_from_p2 == pytest.approx(K3 / got.p2)
    assert got.steps == w + 60 and got.windows == 3
    assert est.predict(seat[0], body[0], est.dt, windows=61).windows.item() == 61  # every start, once
    with pytest.raises(
        ValueError, match=r"windows = 62 is not allowed: 1 to 61 for recording 0: its 260 steps offer 61"
    ):
        est.predict(seat[0], body[0], est.dt, windows=62)


def test_several_recordings_as_2d_array_or_list(est):
    seat, body, _ = recordings(3, 300, est.dt)
    table = est.predict(seat, body, est.dt, windows=4)
    assert list(table.recording) == [0, 1, 2]
    for i in range(3):
        one = est.predict(seat[i], body[i], est.dt, windows=4)
        assert table.iloc[i][["p1", "p2"]].to_numpy() == pytest.approx(one[["p1", "p2"]].to_numpy()[0], rel=1e-6)
    ragged = est.predict([seat[0], seat[1, :250]], [body[0], body[1, :250]], est.dt, windows=4, names=["a", "b"])
    assert list(ragged.recording) == ["a", "b"] and list(ragged.steps) == [300, 250]
    assert ragged.p1.iloc[0] == pytest.approx(table.p1.iloc[0], rel=1e-6)


def test_m3_uses_the_runs_car(tiny_run, est, tmp_path):
    cfg = OmegaConf.load(tiny_run / ".hydra" / "config.yaml")
    cfg.car = {"c3": 600.0, "k3": 90000.0}
    (tmp_path / ".hydra").mkdir()
    OmegaConf.save(cfg, tmp_path / ".hydra" / "config.yaml")
    shutil.copytree(tiny_run / "checkpoints", tmp_path / "checkpoints")
    from hybrid_sysid import load_estimator

    other = load_estimator(tmp_path)
    seat, body, _ = recordings(2, 300, est.dt)
    got, paper = other.predict(seat, body, est.dt), est.predict(seat, body, est.dt)
    assert got.p1.to_numpy() == pytest.approx(paper.p1.to_numpy())  # same network
    assert got.m3_from_p1.to_numpy() == pytest.approx(600.0 / got.p1.to_numpy())
    assert got.m3_from_p2.to_numpy() == pytest.approx(90000.0 / got.p2.to_numpy())


def test_resampled_recording_estimated_nearly_as_well(est):
    """The same roads and seats sampled at dt / 2 and resampled: within twice the native error, averaged over
    ten recordings (a recording read at the wrong rate scales the time axis and misses by ~40% here)."""
    n, steps = 10, 400
    seat, body, true = recordings(n, steps, est.dt)
    native = relative_deviation(est.predict(seat, body, est.dt)[["p1", "p2"]].to_numpy(), true).mean()
    constant = relative_deviation(np.broadcast_to(np.exp(np.log(true).mean(axis=0)), true.shape), true).mean()
    assert native < 0.5 * constant, "the model has not learned enough for this check to mean anything"
    seat2, body2, _ = recordings(n, 2 * steps, est.dt / 2)
    table = est.predict(seat2, body2, est.dt / 2, resample=True)
    assert (table.steps == steps).all()
    assert relative_deviation(table[["p1", "p2"]].to_numpy(), true).mean() < 2 * native


@pytest.mark.parametrize(
    "dt_from, n, expected", [(0.0025, 800, 400), (0.0025, 801, 401), (0.01, 200, 400), (0.004, 500, 400)]
)
def test_resample_keeps_a_sine(dt_from, n, expected):
    """A 7 Hz sine (inside the seat's 3.5-7 Hz resonance band) resampled to 5 ms keeps its amplitude and
    frequency (least-squares fit of a sine) and has ceil(n * up / down) samples; its ends stay close too."""
    dt_to, f0 = 0.005, 7.0
    x = np.sin(2 * np.pi * f0 * np.arange(n) * dt_from + 0.7)
    y = resample_to(x, dt_from, dt_to)
    assert len(y) == expected
    t = np.arange(len(y)) * dt_to
    (amp, f, phase), _ = curve_fit(
        lambda t, a, f, ph: a * np.sin(2 * np.pi * f * t + ph), t[20:-20], y[20:-20], p0=(0.9, 6.9, 0.6)
    )
    assert f == pytest.approx(f0, rel=1e-4) and amp == pytest.approx(1.0, abs=2e-3)
    inside = t <= (n - 1) * dt_from  # an upsampled last sample lies past the input's end
    assert np.abs(y - np.sin(2 * np.pi * f0 * t + 0.7))[inside].max() < 0.05


def test_bad_input_raises_value_error_naming_it(est):
    seat, body, _ = recordings(1, 300, est.dt)
    with pytest.raises(
        ValueError, match=r"recording 0 = 150 steps is not allowed: at least the run's data.window = 200"
    ):
        est.predict(seat[0, :150], body[0, :150], est.dt)
    bad = seat[0].copy()
    bad[17] = np.nan
    with pytest.raises(ValueError, match=r"seat_acc of recording 0 at step 17 = nan is not allowed: finite values"):
        est.predict(bad, body[0], est.dt)
    with pytest.raises(ValueError, match=r"dt = 0.004 is not allowed: the run's data.dt = 0.005 s .*resample=true"):
        est.predict(seat[0], body[0], 0.004)
    with pytest.raises(
        ValueError, match=r"dt = 1e-08 is not allowed: a step that resamples to the run's data.dt = 0.005 s"
    ):
        est.predict(seat[0], body[0], 1e-8, resample=True)
    with pytest.raises(ValueError, match=r"dt = -1 is not allowed: a finite sampling interval > 0"):
        est.predict(seat[0], body[0], -1)
    with pytest.raises(ValueError, match=r"windows = 0 is not allowed: an integer >= 1"):
        est.predict(seat[0], body[0], est.dt, windows=0)
    with pytest.raises(
        ValueError, match=r"recording 0 = shapes \(300,\) and \(299,\) is not allowed: two 1-D arrays of one length"
    ):
        est.predict(seat[0], body[0, :299], est.dt)
    with pytest.raises(ValueError, match=r"seat_acc = shape \(1, 1, 300\) is not allowed: 1-D"):
        est.predict(seat[None], body[None], est.dt)


def test_run_without_network_raises_one_line(tiny_run, tmp_path):
    from hybrid_sysid import load_estimator

    with pytest.raises(
        InputError,
        match=r"run = .* is not allowed: it has no .hydra/config.yaml \(a run directory written by hybrid-sysid\)",
    ):
        load_estimator(tmp_path)
    (tmp_path / ".hydra").mkdir()
    shutil.copy(tiny_run / ".hydra" / "config.yaml", tmp_path / ".hydra")
    with pytest.raises(
        InputError,
        match=r"run = .* is not allowed: a run that trained a network, with checkpoints/best.ckpt or last.ckpt",
    ):
        load_estimator(tmp_path)
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "best.ckpt").write_text("not a checkpoint")
    with pytest.raises(InputError, match=r"its checkpoints/best.ckpt cannot be read"):
        load_estimator(tmp_path)
    cfg = OmegaConf.load(tiny_run / ".hydra" / "config.yaml")
    cfg.model.net.channels = 16
    OmegaConf.save(cfg, tmp_path / ".hydra" / "config.yaml")
    shutil.copy(tiny_run / "checkpoints" / "last.ckpt", tmp_path / "checkpoints")
    with pytest.raises(InputError, match=r"a run whose checkpoints/last.ckpt fits its model.net \(hybrid_sysid"):
        load_estimator(tmp_path, checkpoint="last")


def test_last_checkpoint_when_asked_or_when_best_is_missing(tiny_run, tmp_path):
    from hybrid_sysid import load_estimator

    (tmp_path / ".hydra").mkdir()
    shutil.copy(tiny_run / ".hydra" / "config.yaml", tmp_path / ".hydra")
    (tmp_path / "checkpoints").mkdir()
    shutil.copy(tiny_run / "checkpoints" / "last.ckpt", tmp_path / "checkpoints")
    fallback, last = load_estimator(tmp_path), load_estimator(tiny_run, checkpoint="last")
    for a, b in zip(fallback.net.state_dict().values(), last.net.state_dict().values()):
        assert (a == b).all()
    with pytest.raises(ConfigError, match=r"^checkpoint = 'latest' is not allowed: best or last"):
        load_estimator(tiny_run, checkpoint="latest")


@started_early
def fresh_imports(tmp, env):
    """A new process: what an import loads, in an interpreter that has loaded nothing yet."""
    code = (
        "import sys, hybrid_sysid.physics, hybrid_sysid.cli.train; assert 'torch' not in sys.modules, 'torch loaded'; "
        "from hybrid_sysid import load_estimator; assert 'torch' in sys.modules; "
        "import hybrid_sysid; getattr(hybrid_sysid, 'nothing')"
    )
    return subprocess.run([sys.executable, "-c", code], cwd=tmp, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.integration
def test_importing_physics_or_the_app_does_not_load_torch(fresh_imports):
    # the app's process composes and checks the config (and a sweep's parent launches jobs) without torch, so a
    # refused value comes back in a second
    done = fresh_imports
    assert "AttributeError: module 'hybrid_sysid' has no attribute 'nothing'" in done.stderr
    assert "torch loaded" not in done.stderr


def test_bool_and_complex_arrays_are_refused(est):
    """As float64 a bool array would read as 0 and 1 and a complex one lose its imaginary part."""
    seat, body, _ = recordings(2, 300, est.dt)
    with pytest.raises(
        InputError, match=r"^seat_acc = dtype bool is not allowed: real numbers in m/s\^2 \(a float or "
    ):
        est.predict(seat[0] > 0, body[0], est.dt)
    with pytest.raises(InputError, match=r"^body_acc = dtype complex128 is not allowed: .*, not bool or complex\)$"):
        est.predict(seat, body + 0.5j, est.dt)
    with pytest.raises(InputError, match=r"^seat_acc\[1\] = dtype complex128 is not allowed: real numbers"):
        est.predict([seat[0], seat[1].astype(complex)], list(body), est.dt)
    ints = np.round(seat * 1000).astype(np.int64)  # integer arrays are numbers (mm/s^2 * 1000 here)
    got, want = est.predict(ints, body, est.dt), est.predict(ints.astype(np.float64), body, est.dt)
    assert got.p1.to_numpy() == pytest.approx(want.p1.to_numpy(), rel=1e-12)


def test_values_beyond_float32_are_refused(est):
    """The network reads float32: 1e300 would become inf and the table NaN."""
    seat, body, _ = recordings(2, 300, est.dt)
    huge = seat.copy()
    huge[0, 5] = 1e300
    with pytest.raises(
        InputError,
        match=r"^seat_acc of recording 0 at step 5 = 1e\+300 is not allowed: magnitudes up to 3.40282e\+38, "
        r"float32's range",
    ):
        est.predict(huge, body, est.dt)
    edge = body.copy()
    edge[1, 9] = -float(np.finfo(np.float32).max) * (1 + 1e-6)
    with pytest.raises(
        InputError,
        match=r"^body_acc of recording 1 at step 9 = -3.4028\d*e\+38 is not allowed: magnitudes up to 3.40282e",
    ):
        est.predict(seat, edge, est.dt)


def test_an_estimate_that_is_not_finite_is_refused(est, monkeypatch):
    """Values inside float32's range may still overflow the network's arithmetic (here a stand-in network that
    returns NaN for a window holding a value above 1e30): no NaN row, an error naming the recording."""
    import torch

    class Overflowing(torch.nn.Module):
        def forward(self, x):
            p = torch.ones(len(x), 2)
            return torch.where(x.abs().amax(dim=(1, 2))[:, None] > 1e30, torch.nan, p)

    seat, body, _ = recordings(2, 300, est.dt)
    monkeypatch.setattr(est, "net", Overflowing())
    assert (est.predict(seat, body, est.dt)[["p1", "p2"]].to_numpy() == 1.0).all()
    body[1, 150] = 1e31  # in every window of recording 1
    with pytest.raises(
        InputError,
        match=r"^recording 1 is not allowed: accelerations of the magnitude the run was trained on \(its values, up to "
        r"1e\+31 m/s\^2 in body_acc, overflow the network's float32 arithmetic: the estimate is p1 = nan, p2 = nan\)",
    ):
        est.predict(seat, body, est.dt)


def test_windows_must_fit_in_the_memory_available(est, monkeypatch):
    """Each window of 2 x 200 steps takes 3200 bytes as float64, twice (cut, then stacked), plus 1600 as float32
    for the first 4096 (one chunk): 100 windows need 800000 bytes, 5000 need 5000 * 6400 + 4096 * 1600. The
    refusal comes before anything that size is allocated."""
    import tracemalloc

    import hybrid_sysid.inference.memory as estimator

    seat, body, _ = recordings(2, 5300, est.dt)
    available = [800_000]
    free = "free memory (MemAvailable)"
    monkeypatch.setattr(estimator, "tightest_memory", lambda: None if available[0] is None else (available[0], free))
    assert est.predict(seat[0, :400], body[0, :400], est.dt, windows=100).windows.item() == 100
    tracemalloc.start()
    try:
        with pytest.raises(
            InputError,
            match=r"^windows = 101 is not allowed: 1 to 100 for recording 0 \(400 steps\): 101 windows of 2 x 200 "
            r"steps need 0.000753 GiB of memory .* and 0.000745 GiB is available \(free memory \(MemAvailable\)\)$",
        ):
            est.predict(seat[0, :400], body[0, :400], est.dt, windows=101)
        assert tracemalloc.get_traced_memory()[1] < 200_000  # the peak: far below the 808000 bytes refused
    finally:
        tracemalloc.stop()
    two = ([seat[0, :400], seat[1, :500]], [body[0, :400], body[1, :500]])
    with pytest.raises(
        InputError,
        match=r"^windows = 51 is not allowed: .* for 2 recordings \(the longest, 'b', 500 steps\): 102 windows",
    ):
        est.predict(*two, est.dt, windows=51, names=["a", "b"])
    assert (est.predict(*two, est.dt, windows=50).windows == 50).all()
    available[0] = 5000 * 6400 + 4096 * 1600
    assert est.predict(seat[0], body[0], est.dt, windows=5000).windows.item() == 5000
    with pytest.raises(InputError, match=r"windows = 5001 is not allowed: 1 to 5000 for "):
        est.predict(seat[0], body[0], est.dt, windows=5001)
    available[0] = None  # unknown: no check
    assert est.predict(seat[0], body[0], est.dt, windows=5001).windows.item() == 5001
