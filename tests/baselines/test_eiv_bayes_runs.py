"""`estimator=eiv_bayes` runs like any baseline: exact on clean consistent windows, its estimates those of the
physics layer's Bayes estimate called directly on the same windows, and a config it cannot serve refused in one
line naming the key."""

import numpy as np
import pytest

from hybrid_sysid.baselines.errors_in_variables import PRIOR_FLOOR
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.physics.eiv import fit_eiv, log_p_prior
from hybrid_sysid.physics.eiv.posterior import bayes_fit
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows
from hybrid_sysid.training.build import build_datamodule
from hybrid_sysid.training.run import train

RUN = ["estimator=eiv_bayes", "data=tiny", "data.seat_spread=0.3", "noise.eval_std=[0.0,0.03]"]


def test_the_bayes_run_is_exact_clean_and_equals_the_physics_estimate(compose_cfg, tmp_path):
    cfg = compose_cfg(*RUN)
    record = train(cfg, tmp_path / "run", overrides=RUN)
    assert record["status"] == "completed" and record["steps"] == 0
    rows = {(r["split"], r["noise_std"], r["windows"], r["parameter"]): r for r in record["results"]}
    for key, row in rows.items():
        if key[1] == 0.0:
            assert row["mean_rel_dev"] <= 1e-4, key
    dm = build_datamodule(cfg)
    dm.setup()
    batch = dm.eval_batch("test", 0.03, windows=1)
    seat, body = (batch["signals"][:, i].numpy().astype(np.float64) for i in (0, 1))
    dt = cfg.data.dt
    draws = {k: cfg.baseline.prior[k] for k in ("m3_min", "m3_max", "c3", "k3", "seat_spread")}
    assert draws["seat_spread"] == 0.3 and draws["m3_min"] == cfg.data.m3_min and draws["c3"] == cfg.car.c3
    start = fit_windows(seat, body, dt, "consistent", bandpass_taps(4.0, 20.0, 151, dt)).p
    mean, cov = log_p_prior(*draws.values())
    fit = fit_eiv(seat, body, dt, p0=start, prior=(mean, cov + PRIOR_FLOOR**2 * np.eye(2)))  # eiv_map's prior
    p = bayes_fit(seat, body, dt, fit, draws)
    p = np.where(np.isfinite(p), p, start)  # where the fit is not defined, the least-squares start
    true = batch["params"].numpy().astype(np.float64)
    dev = np.abs(p - true) / true
    for i, name in enumerate(("p1", "p2")):
        assert rows[("test", 0.03, 1, name)]["mean_rel_dev"] == pytest.approx(dev[:, i].mean(), rel=1e-9)


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["baseline.fix=skew"], "baseline.fix"),  # no fault fix: the grid spans p alone
        (["data.seat_spread=0.0"], "baseline.prior.seat_spread"),  # a prior without a density
    ],
)
def test_what_it_cannot_serve_is_one_line_naming_the_key(compose_cfg, overrides, key):
    from hybrid_sysid.config import validate

    with pytest.raises(ConfigError, match=key.replace(".", r"\.")) as info:
        validate(compose_cfg("estimator=eiv_bayes", "data=tiny", "data.seat_spread=0.3", *overrides))
    assert "\n" not in str(info.value)
