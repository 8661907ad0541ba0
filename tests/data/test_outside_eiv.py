"""The errors-in-variables fit over the samples of a recording outside each window (objective=cross_segment's
target "eiv", data/outside.py): physics.eiv's fit where the outside is one segment, exact on clean recordings
wherever the window sits, blind to the window's samples, closer to the truth than the least-squares outside fit
under noise; the objective's ``target`` reaches the data module's fit."""

import pickle

import numpy as np
import pytest
import torch

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.data.outside import OutsideFit
from hybrid_sysid.data.outside_joined import fit_joined
from hybrid_sysid.model.cross_segment import CrossSegmentObjective
from hybrid_sysid.physics import QuarterCar, road_profiles, simulate
from hybrid_sysid.physics.eiv import fit_eiv
from hybrid_sysid.physics.exact import continuous_recordings
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.road import road_amplitudes, road_phases, wave_numbers

DT, N, W = 0.005, 1200, 500
M = N - W
# a window at either end (one segment), next to either end (a segment shorter than the model's transient), inside
STARTS = np.array([0, M, 1, M - 1, 3, M - 3, 9, 350, 120, 580])  # one per recording of ``recordings``


def recordings(model, n=10, seed=3):
    """Clean seat and body accelerations (n, N) of every road class, and their true p: the simulator's consistent
    recordings ("discrete") or exact samples of the continuous motion ("continuous")."""
    rng = np.random.default_rng(seed)
    m3 = rng.uniform(50, 200, n)
    classes = ("ABCDE" * n)[:n]
    if model == "discrete":
        seat, body = simulate(road_profiles(classes, N, DT, 15.0, rng=seed), m3, DT, measurement="consistent")
    else:
        amps, phases = road_amplitudes(list(classes)), road_phases(n, 300, rng)
        seat, body = continuous_recordings(amps, phases, wave_numbers(300) * 15.0, np.arange(n), m3, N, DT)
    return seat, body, np.stack(QuarterCar().parameters(m3), axis=1)


@pytest.mark.parametrize("model", ["discrete", "continuous"])
def test_clean_recordings_give_the_true_p_wherever_the_window_is(model):
    seat, body, truth = recordings(model)
    p, se, ok = fit_joined(seat, body, STARTS, W, DT, model, p0=truth * 1.2)
    assert ok.all()
    assert np.abs(p / truth - 1).max() < (1e-11 if model == "discrete" else 1e-8)  # the [5/4] map's error
    assert (se < 1e-6).all()


@pytest.mark.parametrize("model", ["discrete", "continuous"])
def test_one_segment_is_physics_eiv_fit_of_it(model):
    """A window at the recording's start or end leaves one segment, and no junction: the joined fit is then
    fit_eiv's of that segment (the same transfer polynomials, noise weighting, transient and se)."""
    seat, body, truth = recordings(model, n=4)
    rng = np.random.default_rng(0)
    seat, body = seat + 0.02 * rng.standard_normal(seat.shape), body + 0.02 * rng.standard_normal(seat.shape)
    starts = np.array([0, M, 0, M])
    p, se, ok = fit_joined(seat, body, starts, W, DT, model, p0=truth)
    rest = np.stack([seat[i, W:] if s == 0 else seat[i, :M] for i, s in enumerate(starts)])
    rest_body = np.stack([body[i, W:] if s == 0 else body[i, :M] for i, s in enumerate(starts)])
    want = fit_eiv(rest, rest_body, DT, model=model, p0=truth)
    assert ok.all() and want.converged.all()
    np.testing.assert_allclose(p, want.p, rtol=1e-9)
    np.testing.assert_allclose(se, want.se, rtol=1e-6)


SPEC = DatasetSpec(n_roads=30, n_masses=10, n_steps=N, seed=4, seat_spread=0.3)
FIR = bandpass_taps(4.0, 20.0, 151, DT)


@pytest.fixture(scope="module")
def dataset():
    dm = QuarterCarDataModule(SPEC, window=W, seed=0)
    dm.setup("fit")
    return dm.dataset


def test_the_target_reads_no_sample_of_the_window(dataset):
    rows, starts = np.array([0, 1, 2, 3]), np.array([0, 200, 450, M])
    seat, body = dataset.seat_acc[rows].copy(), dataset.body_acc[rows].copy()
    normals = np.random.default_rng(1).standard_normal((4, 2, N))

    def target(s, b):
        out = OutsideFit(s, b, DT, SPEC.measurement, W, FIR, "eiv").fit(np.arange(4), starts, 0.02, normals)
        return out["p_out"].numpy(), out["se_out"].numpy()

    p, se = target(seat, body)
    assert np.isfinite(p).all()
    garbage = np.random.default_rng(2).standard_normal((2, 4, W)).astype(np.float32) * 50
    s2, b2 = seat.copy(), body.copy()
    for i, s in enumerate(starts):
        s2[i, s : s + W] = garbage[0, i]
        b2[i, s : s + W] = garbage[1, i]
    p2, se2 = target(s2, b2)
    # the least-squares start's FFT filter spreads the window's rounding over the recording (1e-12 or so): the
    # likelihood fit ends where it ends from any start that close
    np.testing.assert_allclose(p2, p, rtol=1e-9)
    np.testing.assert_allclose(se2, se, rtol=1e-6)
    # a sample next to the window is the target's own: the likelihood reads every raw sample outside
    s3 = seat.copy()
    s3[1, starts[1] - 1] += 0.5
    s3[2, starts[2] + W] += 0.5
    p3, _ = target(s3, body)
    assert (np.abs(p3[1:3] / p[1:3] - 1).max(axis=1) > 1e-5).all()


def test_under_noise_it_is_closer_to_the_truth_than_the_least_squares_outside_fit(dataset):
    """Every recording of a seat_spread 0.3 dataset at a random window start, noise 0.03 on both channels: the
    mean error of each parameter and the objective's loss at the true p (its rows weighed by each target's se)."""
    n = len(dataset.params)
    rng = np.random.default_rng(5)
    rows, starts = np.arange(n), rng.integers(0, M + 1, n)
    normals = rng.standard_normal((n, 2, N))
    truth = dataset.params.astype(np.float64)
    objective = CrossSegmentObjective(
        p_scale=[8.0, 1200.0], filter={"low_hz": 4.0, "high_hz": 20.0, "taps": 151}, dt=DT
    )
    error, loss = {}, {}
    for target in ("ls", "eiv"):
        fit = OutsideFit(dataset.seat_acc, dataset.body_acc, DT, SPEC.measurement, W, FIR, target)
        out = fit.fit(rows, starts, 0.03, normals)
        error[target] = np.abs(out["p_out"].numpy() / truth - 1).mean(axis=0)
        loss[target] = objective(torch.from_numpy(truth), out).item()
    # measured: 0.83 / 0.62 of the least squares' mean errors, 0.68 of its loss (0.83-0.88, 0.60-0.68 and
    # 0.68-0.77 over three draws)
    assert (error["eiv"] < 0.95 * error["ls"]).all(), error
    assert loss["eiv"] < 0.85 * loss["ls"], loss


def test_the_objective_hands_its_target_to_the_data_module():
    spec = DatasetSpec(n_roads=6, n_masses=4, n_steps=800, seed=2, seat_spread=0.3)
    band = {"low_hz": 4.0, "high_hz": 20.0, "taps": 101}
    batches = {}
    for target in ("ls", "eiv", None):
        fir, chosen = bandpass_taps(4.0, 20.0, 101, DT), None
        if target is not None:
            objective = CrossSegmentObjective(p_scale=[8.0, 1200.0], filter=band, dt=DT, target=target)
            fir, chosen = objective.outside_fir, objective.outside_target
        dm = QuarterCarDataModule(spec, window=200, seed=3, outside_fir=fir, outside_target=chosen)
        batches[target] = {k: dm.eval_batch("val", std) for k, std in (("clean", 0.0), ("noisy", 0.02))}
    # "ls" is the fit of taps without a target (a config saved before the key existed), to the bit
    for k in ("clean", "noisy"):
        assert torch.equal(batches["ls"][k]["p_out"], batches[None][k]["p_out"])
        assert torch.equal(batches["ls"][k]["se_out"], batches[None][k]["se_out"])
    clean = batches["eiv"]["clean"]  # exact but for the float32 rounding of the stored recordings
    np.testing.assert_allclose(clean["p_out"].numpy(), clean["params"].numpy(), rtol=1e-5)
    assert not torch.equal(batches["eiv"]["noisy"]["p_out"], batches["ls"]["noisy"]["p_out"])


def test_the_target_reaches_the_outside_fit_of_a_pickled_data_module_and_a_bad_target_is_named(make_cfg):
    from hybrid_sysid.training.build import build_datamodule, build_objective

    for overrides, want in (((), "eiv"), (("objective.target=ls",), "ls")):
        cfg = make_cfg(
            "data=tiny", "objective=cross_segment", "data.window=100", "objective.filter.taps=61", *overrides
        )
        objective = build_objective(cfg)
        assert objective.outside_target == want
        dm = pickle.loads(pickle.dumps(build_datamodule(cfg, objective)))  # as a data module built in another process
        dm.setup("fit")
        assert dm.data.outside.target == want
    plain = np.zeros((1, 800))
    assert OutsideFit(plain, plain, DT, SPEC.measurement, 200, np.ones(5)).target == "ls"
    with pytest.raises(ConfigError, match=r"^target = 'tls' is not allowed: one of eiv, ls"):
        OutsideFit(plain, plain, DT, SPEC.measurement, 200, np.ones(5), "tls")
    with pytest.raises(ConfigError, match=r"^target = 'tls' is not allowed: one of eiv, ls"):
        CrossSegmentObjective(
            p_scale=[8.0, 1200.0], filter={"low_hz": 4.0, "high_hz": 20.0, "taps": 101}, dt=DT, target="tls"
        )


def test_the_config_chooses_the_target(make_cfg):
    from hybrid_sysid.training.build import build_objective

    assert build_objective(make_cfg("objective=cross_segment")).outside_target == "eiv"
    assert build_objective(make_cfg("objective=cross_segment", "objective.target=ls")).outside_target == "ls"
