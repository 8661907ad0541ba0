"""`baseline=eiv` and `baseline=eiv_map` run like any baseline and the bound rides on every test row: the fit is
exact on clean consistent windows, its estimates are those of the physics layer's fit called directly on the same
windows, the MAP fit's prior is the simulator's, and each test row carries the Cramér-Rao bound that a direct
computation on the split's clean windows gives."""

import json
import math

import numpy as np
import pytest

from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.model.metrics import bound_fields
from hybrid_sysid.physics.eiv import crb_relative_std, fit_eiv
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows
from hybrid_sysid.training.build import build_datamodule
from hybrid_sysid.training.run import train

TINY = ["data=tiny", "noise.eval_std=[0.0,0.01,0.1]", "evaluation.windows=[1,3]"]


@pytest.fixture(scope="module")
def eiv_run(compose_cfg, tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("eiv") / "run"
    cfg = compose_cfg("baseline=eiv", *TINY)
    return cfg, train(cfg, run_dir, overrides=["baseline=eiv", *TINY]), run_dir


def test_the_eiv_run_is_exact_clean_and_equals_the_physics_fit_on_the_same_windows(eiv_run):
    cfg, record, run_dir = eiv_run
    assert record["status"] == "completed" and record["steps"] == 0
    rows = {(r["split"], r["noise_std"], r["windows"], r["parameter"]): r for r in record["results"]}
    for key, row in rows.items():
        if key[1] == 0.0:  # consistent clean windows: the discrete model is exact
            assert row["mean_rel_dev"] <= 1e-4, key
    # the reference: the physics layer's fit of the same noisy windows, started from band-passed least squares
    dm = build_datamodule(cfg)
    dm.setup()
    batch = dm.eval_batch("test", 0.01, windows=3)
    seat, body = (batch["signals"][:, i].numpy().astype(np.float64) for i in (0, 1))
    start = fit_windows(seat, body, cfg.data.dt, "consistent", bandpass_taps(4.0, 20.0, 151, cfg.data.dt)).p
    p = fit_eiv(seat, body, cfg.data.dt, noise_ratio=1.0, p0=start).p.reshape(-1, 3, 2).mean(axis=1)
    true = batch["params"].numpy().astype(np.float64).reshape(-1, 3, 2)[:, 0]
    dev = np.abs(p - true) / true
    for i, name in enumerate(("p1", "p2")):
        assert rows[("test", 0.01, 3, name)]["mean_rel_dev"] == pytest.approx(dev[:, i].mean(), rel=1e-9)


def test_every_test_row_carries_the_bound_of_a_direct_computation(eiv_run):
    cfg, record, run_dir = eiv_run
    on_disk = json.loads((run_dir / "metrics.json").read_text())
    dm = build_datamodule(cfg)
    dm.setup()
    for k in (1, 3):
        batch = dm.eval_batch("test", 0.0, windows=k)
        seat, body = (batch["signals"][:, i].numpy().astype(np.float64) for i in (0, 1))
        p = batch["params"].numpy().astype(np.float64)
        s = crb_relative_std(seat, body, p, cfg.data.dt, noise_ratio=1.0)
        per_recording = 1 / np.sqrt((s**-2).reshape(-1, k, 2).sum(axis=1))  # K windows: information adds
        for r in on_disk["results"]:
            if r["split"] == "test" and r["windows"] == k:
                i = ("p1", "p2").index(r["parameter"])
                expected = math.sqrt(2 / math.pi) * r["noise_std"] * per_recording[:, i].mean()
                assert r["bound"] == pytest.approx(expected, rel=1e-9)
                assert r["bound_output"] <= r["bound"]  # noise on one channel never costs more than on two
    test = [r for r in on_disk["results"] if r["split"] == "test"]
    assert all(("efficiency" in r) == ("bound" in r) for r in test)
    assert all(r["efficiency"] is None for r in test if r["noise_std"] == 0)
    # the bound is linear in the noise std
    by = {(r["noise_std"], r["windows"], r["parameter"]): r["bound"] for r in test}
    assert by[(0.1, 1, "p1")] == pytest.approx(10 * by[(0.01, 1, "p1")], rel=1e-12)
    assert [r for r in on_disk["results"] if r["split"] != "test" and "bound" in r] == []


def test_a_recording_without_excitation_has_an_infinite_bound_not_a_crash():
    zero = np.zeros((2, 300))
    s = crb_relative_std(zero, zero, np.array([10.0, 500.0]), 0.005)
    assert np.isinf(s).all()
    rows = bound_fields(np.array([[10.0, 500.0]] * 2), np.array([[11.0, 490.0]] * 2), 0.01, s, s)
    assert all(math.isinf(r["bound"]) for r in rows) and all(r["efficiency"] is None for r in rows)


def test_the_map_prior_is_the_simulators_draws(compose_cfg):
    cfg = compose_cfg("baseline=eiv_map", "data=default", "data.seat_spread=0.3")
    fit = ErrorsInVariablesFit(**{k: v for k, v in cfg.baseline.items() if k != "_target_"})
    mean, cov = fit.prior
    # the reference: the simulator's own draws (hybrid_sysid.data.dataset) of m3, C3 and K3, by numpy directly
    rng = np.random.default_rng(7)
    n = 400_000
    m3 = rng.integers(cfg.data.m3_min, cfg.data.m3_max + 1, size=n).astype(float)
    c3 = cfg.car.c3 * rng.uniform(0.7, 1.3, size=n)
    k3 = cfg.car.k3 * rng.uniform(0.7, 1.3, size=n)
    log_p = np.log(np.stack([c3 / m3, k3 / m3], axis=1))
    assert mean == pytest.approx(log_p.mean(axis=0), abs=2e-3)
    assert np.sqrt(np.diag(cov)) == pytest.approx(log_p.std(axis=0), rel=1e-2)
    assert cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]) == pytest.approx(np.corrcoef(log_p.T)[0, 1], abs=1e-2)


def test_a_bad_noise_ratio_is_one_line_naming_the_key(compose_cfg):
    from hybrid_sysid.config import validate
    from hybrid_sysid.core.checks import ConfigError

    with pytest.raises(ConfigError, match="noise_ratio"):
        validate(compose_cfg("baseline=eiv", "data=tiny", "baseline.noise_ratio=-1"))
