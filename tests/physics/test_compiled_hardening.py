"""The hardening fix's compiled displacement recursion against the numpy pass it replaces, and the recursion
against the seat equation it solves."""

import numpy as np
import pytest

from hybrid_sysid.physics.compiled_hardening import numpy_pass, run_pass


def _inputs(implicit, n=7, N=300, seed=0):
    # a seat on a class-C-like window: p1 ~ 5 1/s, p2 ~ 800 1/s^2, kappa ~ 35000 1/m^2 (car=hardening_seat), so
    # that at a millimetre's stroke the cube is a few percent of the linear force and the Newton steps matter
    rng = np.random.default_rng(seed)
    dt = 0.005
    p1, p2 = rng.uniform(3.0, 8.0, n), rng.uniform(500.0, 1200.0, n)
    c = p2 * rng.uniform(0.0, 1e5, n)
    alpha = p1 / dt + (p2 if implicit == 1.0 else p2 / 2.0)
    beta = p1 / dt - (0.0 if implicit == 1.0 else p2 / 2.0)
    rhs = rng.normal(0.0, 2.0, (n, N))
    d, free = np.zeros((n, N)), np.zeros((n, N))
    d[:, 0], free[:, 0] = rng.normal(0.0, 1e-3, n), 1.0
    return d, free, rhs, alpha, beta, implicit * c, (1.0 - implicit) * c, implicit


@pytest.mark.parametrize("implicit", [1.0, 0.5])  # the discrete model's step, the continuous one's trapezoid
@pytest.mark.parametrize("end", [300, 41])  # a whole pass, and a later pass that stops where d_0 no longer reaches
def test_the_compiled_pass_equals_the_numpy_pass_bit_for_bit(implicit, end):
    d, free, rhs, alpha, beta, cubic, explicit, implicit = _inputs(implicit)
    d2, free2 = d.copy(), free.copy()
    numpy_pass(d, free, rhs, alpha, beta, cubic, explicit, implicit, end)
    run_pass(d2, free2, rhs, alpha, beta, cubic, explicit, implicit, end)
    np.testing.assert_array_equal(d2, d)
    np.testing.assert_array_equal(free2, free)
    assert np.all(d2[:, end:] == 0.0)  # past ``end`` nothing is written


def test_the_pass_solves_the_discrete_seat_equation():
    # (p1 / dt + p2) d_k + c d_k^3 = p1 / dt d_{k-1} + rhs_k at every step, and free is d's derivative in d_0
    d, free, rhs, alpha, beta, cubic, explicit, implicit = _inputs(1.0)
    run_pass(d, free, rhs, alpha, beta, cubic, explicit, implicit, d.shape[1])
    left = alpha[:, None] * d[:, 1:] + cubic[:, None] * d[:, 1:] ** 3
    np.testing.assert_allclose(left, beta[:, None] * d[:, :-1] + rhs[:, 1:], rtol=0, atol=1e-12 * np.abs(rhs).max())
    h = 1e-7
    shifted, f2 = d.copy(), free.copy()
    shifted[:, 0] += h
    run_pass(shifted, f2, rhs, alpha, beta, cubic, explicit, implicit, d.shape[1])
    np.testing.assert_allclose((shifted - d) / h, free, rtol=1e-5, atol=1e-9)
