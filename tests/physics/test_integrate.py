"""Re-integration: closed forms, the simulator's own states, and the least-squares recovery of (p1, p2)."""

import numpy as np
import pytest

from hybrid_sysid.physics import QuarterCar, integrate, integrate_trapezoid, relative_states, road_profiles, simulate
from hybrid_sysid.physics.integrate import correct_gain, integrate_corrected

CAR = QuarterCar()


def test_constant_acceleration_closed_form():
    a, dt, n = 2.5, 0.01, 200
    vel, pos = integrate(np.full(n, a), dt)
    k = np.arange(n)
    np.testing.assert_allclose(vel, a * dt * k, rtol=1e-12)
    np.testing.assert_allclose(pos, a * dt**2 * k * (k + 1) / 2, rtol=1e-12)


def simulated(road_class, measurement, dt=0.005, n_steps=1200, seed=0):
    road = road_profiles([road_class] * 2, n_steps, dt, 15.0, rng=seed)
    masses = np.array([[50.0, 137.0, 200.0]] * 2)
    seat, body, states = simulate(road[:, None, :], masses, dt, measurement=measurement, return_states=True)
    return masses, seat, body, states


def rel_error(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


@pytest.mark.parametrize("road_class", list("ABCDE"))
def test_consistent_measurement_reintegrates_to_the_simulator_states(road_class):
    dt = 0.005
    _, seat, body, s = simulated(road_class, "consistent", dt)
    seat_vel, seat_pos = integrate(seat, dt)
    body_vel, body_pos = integrate(body, dt)
    assert rel_error(seat_vel, s["w"]) < 1e-9
    assert rel_error(seat_pos, s["z"]) < 1e-9
    assert rel_error(body_vel, s["v"]) < 1e-9
    assert rel_error(body_pos, s["y"]) < 1e-9
    assert rel_error(seat_vel - body_vel, s["w"] - s["v"]) < 1e-9
    assert rel_error(seat_pos - body_pos, s["z"] - s["y"]) < 1e-9


def least_squares_p(seat, rel_vel, rel_disp):
    """(p1, p2) minimising |seat + p1 rel_vel + p2 rel_disp|^2, per recording, by numpy's lstsq."""
    X = np.stack([-rel_vel, -rel_disp], axis=-1)
    return np.linalg.lstsq(X, seat, rcond=None)[0]


def worst_fit_error(road_class, measurement, dt, paired="measurement"):
    masses, seat, body, _ = simulated(road_class, measurement, dt, n_steps=int(6 / dt), seed="ABCDE".index(road_class))
    if paired == "same_step":  # eq. 22 as written: z'_k - y'_k
        rel_vel, rel_disp = relative_states(seat, body, dt, "paper")
    else:
        rel_vel, rel_disp = relative_states(seat, body, dt, measurement)
    worst = 0.0
    for i in range(masses.shape[0]):
        for j in range(masses.shape[1]):
            p_hat = least_squares_p(seat[i, j], rel_vel[i, j], rel_disp[i, j])
            worst = max(worst, np.max(np.abs(p_hat / np.array(CAR.parameters(masses[i, j])) - 1)))
    return worst


@pytest.mark.parametrize("road_class", list("ABCDE"))
@pytest.mark.parametrize("dt", [0.001, 0.005])
def test_consistent_data_give_back_p_by_least_squares(road_class, dt):
    # the seat equation holds exactly up to float64 rounding, so the fit misses p by rounding only (~1e-11)
    assert worst_fit_error(road_class, "consistent", dt) < 1e-9


def test_the_defaults_of_simulate_and_relative_states_fit_together():
    # a recording and a pairing from different schemes bias the fit by 1-150% (test below): the two public
    # functions called with their defaults must use the same one
    dt = 0.005
    road = road_profiles(["C"], 1200, dt, 15.0, rng=0)
    m3 = np.array([60.0, 170.0])
    seat, body = simulate(road, m3, dt)
    rel_vel, rel_disp = relative_states(seat, body, dt)
    for i in range(2):
        p_hat = least_squares_p(seat[i], rel_vel[i], rel_disp[i])
        np.testing.assert_allclose(p_hat, CAR.parameters(m3[i]), rtol=1e-9)


@pytest.mark.parametrize("road_class", list("ABCE"))
def test_paper_measurement_biases_the_fit(road_class):
    # docs/discretisation.md, "The hybrid objective and the discretisation": re-integrating eq.-12 recordings does not
    # give the simulator's states back
    assert worst_fit_error(road_class, "paper", 0.001) > 0.5
    # the consistent recording with eq. 22's same-step pairing leaves a bias of about dt p1 y''
    assert 0.002 < worst_fit_error(road_class, "consistent", 0.001, paired="same_step") < 0.03


def test_the_gain_correction_is_fourth_order_and_leaves_constants_and_ramps():
    """Reference: the closed-form integrals of a = 1 - cos(omega t) from rest. a(0) = a'(0) = 0, so the start
    leaves no second-order error (``integrate_corrected``) and nothing but the rule's gain errs."""
    omega, errors = 2 * np.pi * 9.0, []
    for dt in (0.004, 0.002):
        t = dt * np.arange(int(1.0 / dt) + 1)
        vel, pos = integrate_corrected(1 - np.cos(omega * t), dt)
        want_vel, want_pos = t - np.sin(omega * t) / omega, t**2 / 2 - (1 - np.cos(omega * t)) / omega**2
        errors.append([np.abs(vel - want_vel)[1:-1].max(), np.abs(pos - want_pos)[2:-2].max()])
    ratio = np.array(errors[0]) / np.array(errors[1])
    assert ((12 < ratio) & (ratio < 20)).all()  # halving dt divides the error by 2^4 (the plain rule's by 2^2)
    k = np.arange(50.0)
    for x in (np.full(50, 3.7e4), 2.5 + 0.3 * k):
        np.testing.assert_allclose(correct_gain(x), x, rtol=1e-14, atol=0)


def test_the_correction_is_the_3_tap_filter_with_its_edges_extrapolated_linearly():
    """Reference: numpy's convolution with [-1/12, 7/6, -1/12] of the rows padded by one linearly extrapolated
    sample at each end, which leaves the edge samples as they are."""
    x = np.random.default_rng(0).standard_normal((3, 40))
    padded = np.concatenate([2 * x[:, :1] - x[:, 1:2], x, 2 * x[:, -1:] - x[:, -2:-1]], axis=1)
    want = np.stack([np.convolve(row, [-1 / 12, 7 / 6, -1 / 12], mode="valid") for row in padded])
    np.testing.assert_allclose(correct_gain(x), want, rtol=0, atol=1e-14)
    vel = integrate_corrected(x, 0.005)[0]
    np.testing.assert_array_equal(vel, correct_gain(integrate_trapezoid(x, 0.005)[0]))
    np.testing.assert_array_equal(
        relative_states(x, 0.5 * x, 0.005, "continuous")[1], integrate_corrected(0.5 * x, 0.005)[1]
    )
