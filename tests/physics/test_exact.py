"""The continuous measurement (physics.exact) against scipy's ODE solver on the analytic road, at tight tolerance."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm as scipy_expm

from hybrid_sysid.physics import (
    QuarterCar,
    continuous_recordings,
    expm,
    integrate_trapezoid,
    relative_states,
    road_amplitudes,
    road_phases,
    wave_numbers,
)


def test_expm_equals_scipys():
    car = QuarterCar()
    a = np.stack([car.system_matrix(m) * dt for m in (50.0, 200.0) for dt in (0.001, 0.005, 0.03)])
    for got, ref in zip(expm(a), a):
        np.testing.assert_allclose(got, scipy_expm(ref), rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize(
    "m3, c3, k3, road_class", [(50.0, 615.0, 98935.0, "E"), (137.0, 700.0, 80000.0, "A"), (200.0, 615.0, 98935.0, "C")]
)
def test_continuous_recording_agrees_with_solve_ivp(m3, c3, k3, road_class):
    dt, n_steps, speed, n_waves = 0.005, 400, 15.0, 300
    car = QuarterCar(m1=130.5, k2=208839.4)  # any car: not only the default one
    amps = road_amplitudes([road_class], n_waves)
    phases = road_phases(1, n_waves, np.random.default_rng(7))
    omegas = wave_numbers(n_waves) * speed
    seat, body = continuous_recordings(amps, phases, omegas, [0], [m3], n_steps, dt, car, c3=[c3], k3=[k3])

    a = QuarterCar(car.m1, car.m2, car.k1, car.k2, k3, car.c2, c3).system_matrix(m3)

    def rhs(t, rho):  # eq. 10 with the analytic road of eq. 6
        r = np.sum(amps[0] * np.sin(omegas * t - phases[0]))
        f = np.zeros(6)
        f[2] = car.k1 / car.m1 * r
        return a @ rho + f

    t = dt * np.arange(n_steps)
    sol = solve_ivp(rhs, (0.0, t[-1]), np.zeros(6), t_eval=t, method="DOP853", rtol=1e-12, atol=1e-14)
    acc = a[:2] @ sol.y  # seat and body rows carry no road term
    for got, ref in ((seat[0], acc[0]), (body[0], acc[1])):
        assert np.max(np.abs(got - ref)) <= 1e-8 * np.max(np.abs(ref))


def test_trapezoid_rule_is_exact_on_a_quadratic_and_second_order_on_a_sine():
    dt = 0.01
    t = dt * np.arange(200)
    vel, pos = integrate_trapezoid(np.ones_like(t), dt)  # a = 1 from rest: v = t, x = t^2 / 2 (trapezoid exact)
    np.testing.assert_allclose(vel, t, atol=1e-12)
    np.testing.assert_allclose(pos, t**2 / 2, rtol=0, atol=1e-4 * dt)  # x integrates a linear v: exact too
    errors = []
    for h in (0.01, 0.005):
        tt = h * np.arange(int(2.0 / h) + 1)
        v, _ = integrate_trapezoid(np.cos(3 * tt), h)
        errors.append(np.max(np.abs(v - np.sin(3 * tt) / 3)))
    assert 3.5 < errors[0] / errors[1] < 4.5  # halving dt quarters the error


def test_continuous_seat_equation_holds_to_the_trapezoid_error():
    dt, n_steps = 0.002, 2000
    amps = road_amplitudes(["C"], 300)
    phases = road_phases(1, 300, np.random.default_rng(1))
    seat, body = continuous_recordings(amps, phases, wave_numbers(300) * 15.0, [0], [90.0], n_steps, dt)
    p1, p2 = QuarterCar().parameters(90.0)
    rel_vel, rel_disp = relative_states(seat, body, dt, "continuous")
    residual = seat + p1 * rel_vel + p2 * rel_disp
    assert np.sqrt(np.mean(residual**2)) < 0.02 * np.sqrt(np.mean(seat**2))
