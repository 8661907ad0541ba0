"""The quarter car against eq. 7-9 written out and against scipy's ODE solver."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hybrid_sysid.physics import QuarterCar, simulate, stable_dt_limit, step

CAR = QuarterCar()


def eq7_to_9(state, m3, r=0.0, c=CAR):
    """The paper's eq. 7-9 for the state (z', y', x', z, y, x)."""
    zd, yd, xd, z, y, x = state
    zdd = -c.c3 / m3 * (zd - yd) - c.k3 / m3 * (z - y)
    ydd = -c.c3 / c.m2 * (yd - zd) - c.c2 / c.m2 * (yd - xd) - c.k3 / c.m2 * (y - z) - c.k2 / c.m2 * (y - x)
    xdd = -c.c2 / c.m1 * (xd - yd) - c.k2 / c.m1 * (x - y) - c.k1 / c.m1 * (x - r)
    return np.array([zdd, ydd, xdd, zd, yd, xd])


def test_system_matrix_is_eq7_to_9():
    rng = np.random.default_rng(0)
    for m3 in (50.0, 123.0, 200.0):
        state = rng.standard_normal(6)
        f = np.array([0, 0, CAR.k1 / CAR.m1 * 0.3, 0, 0, 0])
        np.testing.assert_allclose(CAR.system_matrix(m3) @ state + f, eq7_to_9(state, m3, r=0.3), rtol=1e-12)


def eq11(u, v, w, x, y, z, r, m3, h, c=CAR):
    """The paper's eq. 11 as printed: u, then v with u_{k+1}, then w with v_{k+1}, then the positions."""
    u1 = u + h * (c.c2 / c.m1 * v - c.c2 / c.m1 * u + c.k2 / c.m1 * y - (c.k1 + c.k2) / c.m1 * x + c.k1 / c.m1 * r)
    v1 = v + h * (
        c.c3 / c.m2 * w
        - (c.c2 + c.c3) / c.m2 * v
        + c.c2 / c.m2 * u1
        + c.k3 / c.m2 * z
        - (c.k2 + c.k3) / c.m2 * y
        + c.k2 / c.m2 * x
    )
    w1 = w + h * (-c.c3 / m3 * w + c.c3 / m3 * v1 - c.k3 / m3 * z + c.k3 / m3 * y)
    return u1, v1, w1, x + h * u1, y + h * v1, z + h * w1


OTHER_CAR = QuarterCar(m1=120.0, m2=1800.0, k1=50000.0, k2=1.2e5, k3=8e4, c2=4000.0, c3=700.0)


@pytest.mark.parametrize("car", [CAR, OTHER_CAR])
def test_step_is_eq11_and_records_what_it_applied_or_eq12(car):
    rng = np.random.default_rng(1)
    state = rng.standard_normal((6, 5))  # u, v, w, x, y, z of five recordings
    r, m3, h = rng.standard_normal(5), rng.uniform(50.0, 200.0, 5), 3e-3
    p1, p2 = car.parameters(m3)
    *new, seat, body = step(*state, r, p1, p2, h, car.coefficients(), True)
    want = eq11(*state, r, m3, h, car)
    np.testing.assert_allclose(new, want, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(seat, (want[2] - state[2]) / h, rtol=1e-9)
    np.testing.assert_allclose(body, (want[1] - state[1]) / h, rtol=1e-9)
    *same, seat12, body12 = step(*state, r, p1, p2, h, car.coefficients(), False)
    np.testing.assert_array_equal(same, new)
    u, v, w, x, y, z = state
    acc = eq7_to_9(np.stack([w, v, u, z, y, x]), m3, c=car)  # eq. 12 is eq. 7-8 at the states of step k
    np.testing.assert_allclose(seat12, acc[0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(body12, acc[1], rtol=1e-12, atol=1e-12)


def test_parameter_ranges():
    p1, p2 = CAR.parameters(np.array([200.0, 50.0]))
    np.testing.assert_allclose(p1, [615 / 200, 615 / 50])
    np.testing.assert_allclose(p2, [98935 / 200, 98935 / 50])


def smooth_road(t):
    return 0.01 * np.sin(7.0 * t) + 0.004 * np.sin(31.0 * t + 1.0) + 0.002 * np.sin(63.0 * t + 2.0)


def reference(m3, t_end):
    def rhs(t, s):
        return CAR.system_matrix(m3) @ s + np.array([0, 0, CAR.k1 / CAR.m1 * smooth_road(t), 0, 0, 0])

    sol = solve_ivp(rhs, (0, t_end), np.zeros(6), method="DOP853", rtol=1e-11, atol=1e-13, dense_output=True)
    return sol.sol


@pytest.mark.parametrize("m3", [50.0, 140.0])
def test_converges_to_solve_ivp_at_first_order(m3):
    t_end = 2.0
    ref = reference(m3, t_end)
    errors = []
    for dt in (4e-3, 2e-3, 1e-3, 5e-4):
        n = int(round(t_end / dt))
        t = dt * np.arange(n)
        seat, body, states = simulate(smooth_road(t)[None], np.array([m3]), dt, measurement="paper", return_states=True)
        exact = ref(t)  # rows: z', y', x', z, y, x
        err = max(
            np.abs(states["z"][0] - exact[3]).max() / np.abs(exact[3]).max(),
            np.abs(states["y"][0] - exact[4]).max() / np.abs(exact[4]).max(),
            np.abs(seat[0] - eq7_to_9(exact, m3)[0]).max() / np.abs(eq7_to_9(exact, m3)[0]).max(),
        )
        errors.append(err)
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert errors[-1] < 0.02
    np.testing.assert_allclose(ratios, 2.0, atol=0.3)  # first order: error halves with dt


def test_paper_measurement_is_eq12_of_the_states():
    dt = 2e-3
    road = smooth_road(dt * np.arange(500))[None]
    seat, body, s = simulate(road, np.array([80.0]), dt, measurement="paper", return_states=True)
    state = np.stack([s["w"], s["v"], s["u"], s["z"], s["y"], s["x"]])[:, 0]
    acc = eq7_to_9(state, 80.0)
    np.testing.assert_allclose(seat[0], acc[0], rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(body[0], acc[1], rtol=1e-10, atol=1e-14)


def test_broadcast_roads_by_masses_equals_one_by_one():
    dt = 5e-3
    roads = np.stack([smooth_road(dt * np.arange(300)), 2 * smooth_road(dt * np.arange(300) + 1)])
    masses = np.array([[60.0, 150.0, 190.0], [55.0, 75.0, 200.0]])
    seat, body = simulate(roads[:, None, :], masses, dt)
    for i in range(2):
        for j in range(3):
            s1, b1 = simulate(roads[i], masses[i, j], dt)
            np.testing.assert_allclose(seat[i, j], s1, rtol=1e-13, atol=1e-16)


def test_stable_dt_limit_separates_bounded_from_growing():
    limit = stable_dt_limit(CAR, 50, 200)
    assert 0.005 < limit < 0.2
    impulse = np.zeros(4000)
    impulse[:5] = 0.01
    stable, _ = simulate(impulse[None], np.array([50.0]), 0.95 * limit)
    with np.errstate(all="ignore"):  # the unstable run overflows
        unstable, _ = simulate(impulse[None], np.array([50.0]), 1.05 * limit)
    assert np.abs(stable[0, -500:]).max() < np.abs(stable[0]).max()
    late = np.abs(unstable[0, -500:])
    assert not np.isfinite(late).all() or late.max() > 1e3 * np.abs(unstable[0, :500]).max()


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="measurement = 'foo' is not allowed: one of paper, consistent"):
        simulate(np.zeros(10), 100.0, 0.01, measurement="foo")
    with pytest.raises(ValueError, match="dt = -0.1 is not allowed: must be > 0"):
        simulate(np.zeros(10), 100.0, -0.1)
    with pytest.raises(ValueError, match="m3 = 0.0 is not allowed: masses > 0"):
        simulate(np.zeros(10), 0.0, 0.01)
