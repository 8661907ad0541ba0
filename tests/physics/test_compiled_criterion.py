"""The fault fix's compiled criterion against the numpy criterion it replaces (physics.eiv.fault_criterion),
on the spectra of simulated windows with noise on both channels: V, its half gradient and both Hessians, for
each fix with a body factor of its own (gain, skew) and for the hardening's cubic regressor. The numpy criterion
is itself held to scipy's least squares and to exact recovery in tests/physics/test_eiv*.py."""

import numpy as np
import pytest

from hybrid_sysid.physics import QuarterCar, road_profiles, seat_car, simulate
from hybrid_sysid.physics.eiv.fault_criterion import evaluate_fault, evaluate_fault_numpy
from hybrid_sysid.physics.eiv.model import frequency_grid
from hybrid_sysid.physics.faults.registry import fix_code

DT, N = 0.005, 500


def _spectra(n=12, seed=0):
    rng = np.random.default_rng(seed)
    road = road_profiles(list("BCDE"), N, DT, 15.0, rng=seed)[np.arange(n) % 4]
    car = QuarterCar()
    car = seat_car(car, n, car.c3 * rng.uniform(0.7, 1.3, n), car.k3 * rng.uniform(0.7, 1.3, n))
    seat, body = simulate(road, rng.integers(50, 201, size=n).astype(float), DT, car, measurement="consistent")
    seat = seat + rng.normal(0.0, 0.03, seat.shape)
    body = body + rng.normal(0.0, 0.03, body.shape)
    return np.fft.rfft(seat, axis=1), np.fft.rfft(body, axis=1), rng


def _theta(rng, n):
    # around the paper's seat (p1 ~ 5-15 1/s, p2 ~ 100-400 1/s^2), the fault's parameter on both sides of 0
    return np.column_stack(
        [np.log(rng.uniform(4.0, 16.0, n)), np.log(rng.uniform(80.0, 400.0, n)), rng.uniform(-0.4, 0.4, n)]
    )


def _close(new, ref):
    # relative to each output's largest entry: the half gradient is a sum of terms far larger than itself
    for a, b in zip(new, ref):
        scale = np.abs(b).max()
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-11 * scale)


@pytest.mark.parametrize("fix, edges", [("gain", (0, 0)), ("skew", (3, 2)), ("hardening", (0, 0))])
@pytest.mark.parametrize("lam", [0.0, 1.0])
def test_the_compiled_criterion_equals_numpy_s(fix, edges, lam):
    S, U, rng = _spectra()
    n = len(S)
    code, grid = fix_code(fix), frequency_grid("discrete", DT, N, *edges)
    theta = _theta(rng, n)
    X = XA = None
    if fix == "hardening":  # the cube of the displacement's spectrum and its A-weighted twin, of a realistic size
        X = 1e-2 * np.abs(S).mean() * (rng.normal(size=S.shape) + 1j * rng.normal(size=S.shape))
        XA = 1e-3 * (rng.normal(size=S.shape) + 1j * rng.normal(size=S.shape))
    ref = evaluate_fault_numpy(theta, S, U, X, code, grid, lam, N, XA=XA)
    _close(evaluate_fault(theta, S, U, X, code, grid, lam, N, XA=XA), ref)
    V, *rest = evaluate_fault(theta, S, U, X, code, grid, lam, N, derivatives=False, XA=XA)
    np.testing.assert_allclose(V, ref[0], rtol=1e-12)
    assert rest == [None, None, None]
    # a few windows alone, as the Newton iterations' tail evaluates them: the same rows
    rows = np.array([1, 7])
    part = evaluate_fault(
        theta[rows],
        S[rows],
        U[rows],
        None if X is None else X[rows],
        code,
        grid,
        lam,
        N,
        XA=None if XA is None else XA[rows],
    )
    _close(part, [r[rows] for r in ref])


def test_a_window_that_is_not_finite_leaves_the_others_alone():
    S, U, rng = _spectra(n=4)
    code, grid = fix_code("gain"), frequency_grid("discrete", DT, N)
    theta = _theta(rng, 4)
    S[2, 5] = np.nan
    V, g, gn, ex = evaluate_fault(theta, S, U, None, code, grid, 1.0, N)
    ref = evaluate_fault_numpy(theta, S, U, None, code, grid, 1.0, N)
    assert np.isnan(V[2]) and np.isnan(ref[0][2])
    keep = np.array([0, 1, 3])
    _close([V[keep], g[keep], gn[keep], ex[keep]], [r[keep] for r in ref])
