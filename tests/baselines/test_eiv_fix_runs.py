"""`baseline=eiv` with `baseline.fix` and the presets `estimator=eiv_fix`, `estimator=eiv_map_fix`: the fix follows
the config's fault as `estimator=ls_fix`'s does, a bad value is one line naming its key, the baseline recovers p on
clean faulty windows of the data module where least squares with the same fix does not quite, and a run with it
scores the physics layer's fit of the same windows."""

import numpy as np
import pytest

from hybrid_sysid.baselines import ErrorsInVariablesFit, LeastSquaresFit
from hybrid_sysid.baselines.fixes import fit_gain
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.physics.eiv import fit_eiv
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.training.build import build_baseline, build_datamodule
from hybrid_sysid.training.run import train

TINY = ["data=tiny", "noise.eval_std=[0.0,0.01]", "evaluation.windows=[1]"]
FIXES_OF_FAULTS = {"clean": "none", "gain": "gain", "skewed": "skew", "lowpass": "skew", "hardening": "hardening"}


@pytest.mark.parametrize("estimator", ["eiv_fix", "eiv_map_fix"])
def test_the_presets_take_the_faults_fix(compose_cfg, estimator):
    for fault, fix in FIXES_OF_FAULTS.items():
        cfg = compose_cfg(f"estimator={estimator}", f"fault={fault}", "data=tiny")
        assert cfg.baseline.fix == fix, fault
        baseline = build_baseline(cfg)
        assert isinstance(baseline, ErrorsInVariablesFit) and baseline.fix == fix
        assert (baseline.prior is not None) == (estimator == "eiv_map_fix")
        assert baseline.skew_max == 0.02
    # the same choice as least squares makes
    cfg = compose_cfg("estimator=ls_fix", "fault=lowpass", "data=tiny")
    assert cfg.baseline.fix == "skew"


def test_a_bad_fix_or_skew_max_is_one_line_naming_the_key(compose_cfg):
    from hybrid_sysid.config import validate

    with pytest.raises(ConfigError) as error:
        validate(compose_cfg("baseline=eiv", "data=tiny", "baseline.fix=drift"))
    assert str(error.value) == "baseline.fix = 'drift' is not allowed: one of none, gain, skew, hardening"
    with pytest.raises(ConfigError, match=r"^baseline\.skew_max = -0\.01 is not allowed") as error:
        validate(compose_cfg("baseline=eiv", "data=tiny", "baseline.skew_max=-0.01"))
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("fault", ["gain", "skewed", "hardening"])
def test_on_clean_faulty_windows_the_fix_is_exact_where_the_plain_fit_is_not(compose_cfg, fault):
    cfg = compose_cfg("estimator=eiv_fix", f"fault={fault}", "data=tiny", "data.seat_spread=0.3")
    dm = build_datamodule(cfg)
    dm.setup()
    fixed = build_baseline(cfg)
    plain = ErrorsInVariablesFit(dt=cfg.data.dt)
    ls = LeastSquaresFit(span="window", filter="bandpass", dt=cfg.data.dt, fix=fixed.fix)
    errors = {}
    for name, estimator in (("fixed", fixed), ("plain", plain), ("ls", ls)):
        pred, true = estimator.predict_split(dm, "test", 0.0)
        errors[name] = np.abs(pred / true - 1).max(axis=0)
    # the stored channels are float32: measured worst 5e-8 (gain), 2e-7 (skew), 6e-8 (hardening); least squares
    # with the fix 2e-7, 1.3e-3 and 7e-3, the plain fit 0.03, 0.3 and 3e-3
    assert (errors["fixed"] < 1e-5).all(), errors
    assert (errors["plain"] > 1e-3).any(), errors  # the fault biases the plain fit
    # no less exact than least squares with the same fix, beyond that rounding
    assert (errors["fixed"] <= np.maximum(errors["ls"], 1e-6)).all(), errors


def test_a_run_with_the_gain_fix_scores_the_physics_fit_of_the_same_windows(compose_cfg, tmp_path):
    overrides = ["baseline=eiv", "baseline.fix=gain", "fault=gain", *TINY]
    cfg = compose_cfg(*overrides)
    record = train(cfg, tmp_path / "run", overrides=overrides)
    assert record["status"] == "completed" and record["steps"] == 0
    rows = {(r["split"], r["noise_std"], r["parameter"]): r for r in record["results"]}
    for key, row in rows.items():
        if key[1] == 0.0:  # clean faulty windows: p to the float32 channels' rounding
            assert row["mean_rel_dev"] <= 1e-5, key
    # the reference: the physics layer's fit of the same noisy windows, started from least squares with the gain fix
    dm = build_datamodule(cfg)
    dm.setup()
    batch = dm.eval_batch("test", 0.01)
    seat, body = (batch["signals"][:, i].numpy().astype(np.float64) for i in (0, 1))
    start = fit_gain(seat, body, cfg.data.dt, "consistent", bandpass_taps(4.0, 20.0, 151, cfg.data.dt))
    p = fit_eiv(seat, body, cfg.data.dt, p0=start, fix="gain").p
    true = batch["params"].numpy().astype(np.float64)
    dev = np.abs(p - true) / true
    for i, name in enumerate(("p1", "p2")):
        assert rows[("test", 0.01, name)]["mean_rel_dev"] == pytest.approx(dev[:, i].mean(), rel=1e-9)
