"""A fault registered from outside the package with a fix of its own (tests/plugins/faults/body_gain_fault.py):
the least-squares and likelihood fits take its fix by name and run its code, which recovers the true p of clean
recordings (the car's C3 / m3, K3 / m3) and the body sensor's gain where the plain fits are biased by it."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from hybrid_sysid.baselines import LeastSquaresFit
from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.physics import QuarterCar, road_profiles, simulate
from hybrid_sysid.physics.eiv import fit_eiv
from hybrid_sysid.physics.faults import fix_for, fixes, register, unregister
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows

PLUGIN = Path(__file__).resolve().parents[1] / "plugins" / "faults" / "body_gain_fault.py"
DT, N, W = 0.005, 1200, 500
GAINS = np.array([0.9, 1.06, 1.12])  # the body sensor's gain per recording


def load_plugin():
    loader = importlib.util.spec_from_file_location("body_gain_fault", PLUGIN)
    module = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(module)
    return module


@pytest.fixture
def plugin():
    module = load_plugin()
    register(module.BodyGain)
    yield module
    unregister("body_gain")


@pytest.fixture(scope="module")
def recordings():
    """Clean consistent recordings, their body channel as the faulty sensor records it, and the true p."""
    m3 = np.array([60.0, 110.0, 180.0])
    seat, body = simulate(road_profiles(["C", "D", "E"], N, DT, 15.0, rng=5), m3, DT, measurement="consistent")
    return seat, GAINS[:, None] * body, np.stack(QuarterCar().parameters(m3), axis=1)


def test_its_fix_joins_the_choice(plugin):
    assert fixes() == ("none", "gain", "skew", "hardening", "body_gain")
    assert fix_for({"body_gain_spread": 0.05}, {}) == "body_gain"
    assert fix_for({"body_gain_spread": 0.05, "skew_max": 0.01}, {}) == "body_gain"  # its rank comes first


def test_least_squares_runs_its_fix_and_recovers_p(plugin, recordings):
    seat, body, truth = recordings
    fir = bandpass_taps(4.0, 20.0, 151, DT)
    plain = fit_windows(seat[:, 300 : 300 + W], body[:, 300 : 300 + W], DT, "consistent", fir).p
    assert np.abs(plain / truth - 1).max() > 0.01  # the fault is visible to the plain fit: 0.13 off
    ls = LeastSquaresFit(span="window", filter="bandpass", dt=DT, fix="body_gain")
    before = plugin.BodyGainFix.calls
    got = np.stack([ls.estimate(seat[i], body[i], DT, "consistent", window=W, windows=3) for i in range(3)])
    assert plugin.BodyGainFix.calls == before + 3
    # measured worst 3e-13: the model is exact on consistent recordings
    assert np.abs(got / truth[:, None] - 1).max() < 1e-8


def test_the_likelihood_runs_its_fix_and_recovers_p_and_the_gain(plugin, recordings):
    seat, body, truth = (x[:, 300 : 300 + W] if x.ndim == 2 and x.shape[1] == N else x for x in recordings)
    before = plugin.BodyGainFix.calls
    fit = fit_eiv(seat, body, DT, p0=truth * 1.2, fix="body_gain")
    assert plugin.BodyGainFix.calls > before
    assert fit.converged.all()
    assert np.abs(fit.p / truth - 1).max() < 1e-8  # measured worst 5e-14 on p and 3e-15 on b
    assert np.abs(fit.fault - GAINS).max() < 1e-8
    assert np.abs(fit_eiv(seat, body, DT, p0=truth).p / truth - 1).max() > 0.01  # the plain fit: 0.13 off
    # the baseline starts from least squares with the same fix (estimator=eiv_fix)
    p, se = ErrorsInVariablesFit(dt=DT, fix="body_gain").fit_windows(seat, body, DT, "consistent")
    assert np.abs(p / truth - 1).max() < 1e-8
    assert np.isfinite(se).all()


def test_a_fix_not_registered_is_refused_in_one_line():
    assert "body_gain" not in fixes()
    for make in (
        lambda: LeastSquaresFit(span="window", filter="bandpass", dt=DT, fix="body_gain"),
        lambda: ErrorsInVariablesFit(dt=DT, fix="body_gain"),
        lambda: fit_eiv(np.zeros((1, W)), np.zeros((1, W)), DT, fix="body_gain"),
    ):
        with pytest.raises(ConfigError) as caught:
            make()
        assert str(caught.value).startswith("fix = 'body_gain'") and "hardening" in str(caught.value)
        assert "\n" not in str(caught.value)


def test_a_fix_is_declared_once_and_taken_by_name():
    module = load_plugin()

    class Twin(module.BodyGain):  # the same fix's code again under another fault
        name = "twin"
        settings = (module.BodyGain.settings[0].__class__("twin_spread", 0.0, "a twin", high=0.5),)

    class Misnamed(Twin):
        fix = "twin"  # its code is named body_gain

    class Borrower(Twin):
        fix, fix_code = "body_gain", None  # takes a registered fault's fix: none is

    for fault in (Misnamed, Borrower):
        with pytest.raises(TypeError, match="fix"):
            register(fault)
    register(module.BodyGain)
    try:
        with pytest.raises(TypeError, match="fix"):
            register(Twin)
        register(Borrower)  # now body_gain is registered
        unregister("twin")
    finally:
        unregister("body_gain")
