"""The linear quarter car solved exactly between samples: ``measurement = "continuous"``.

An accelerometer samples the true, continuous motion every dt; no step of a discrete scheme does that. The road
is analytic (eq. 6: r(t) = sum_i A_i sin(Omega_i t - phi_i), Omega_i = w_i v), so eq. 10, rho' = A rho + b r(t),
has a closed-form solution from the zero state at t = 0:

    rho(t) = rho_p(t) - e^{A t} rho_p(0),   rho_p(t) = Im sum_i (j Omega_i I - A)^{-1} b A_i e^{j(Omega_i t - phi_i)}

(rho_p is the steady response to each sine; the second term makes rho(0) = 0). It is sampled at t_k = k dt and
the seat and body accelerations are rows 0 and 1 of A rho (the road enters the wheel row only). e^{A dt} comes
from scaling and squaring of its Taylor series, and e^{A t_k} rho_p(0) from stepping it k times, so the solution
carries no time-stepping error: it agrees with scipy's solve_ivp at tight tolerance
(tests/physics/test_exact.py). Plain numpy.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hybrid_sysid.core.checks import bad
from hybrid_sysid.physics.quarter_car import QuarterCar, seat_car

CHUNK = 256  # recordings per block: bounds the (recordings, waves, 6, 6) solve and the (recordings, steps) output


def expm(a: np.ndarray) -> np.ndarray:
    """e^a for a batch of square matrices (..., n, n): scaling and squaring with an order-18 Taylor series
    (after scaling the norm is <= 0.5, where the truncation error is below 1e-22)."""
    a = np.asarray(a, dtype=np.float64)
    norm = np.abs(a).sum(axis=-2).max()  # the 1-norm of the largest matrix
    squarings = max(0, int(np.ceil(np.log2(norm / 0.5)))) if norm > 0 else 0
    a = a / 2.0**squarings
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    result, term = eye.copy(), eye.copy()
    for k in range(1, 19):
        term = term @ a / k
        result = result + term
    for _ in range(squarings):
        result = result @ result
    return result


def continuous_recordings(
    amplitudes: np.ndarray,
    phases: np.ndarray,
    omegas: np.ndarray,
    road_of,
    m3,
    n_steps: int,
    dt: float,
    car: QuarterCar = QuarterCar(),
    c3=None,
    k3=None,
):
    """Seat and body accelerations (z'', y'') of every recording i on road ``road_of[i]`` with mass ``m3[i]``,
    sampled at t_k = k dt, k = 0..n_steps-1, from the exact solution of eq. 10 (module docstring).

    amplitudes, phases: (n_roads, n_waves), A_i and phi_i of each road; omegas: (n_waves,), the time
    frequencies Omega_i = w_i v (rad/s). c3, k3: per-recording seat constants in place of the car's.
    Returns two float64 arrays (n_recordings, n_steps).
    """
    if car.seat_hardening:  # superposing the sines' responses needs a linear car
        bad("car.seat_hardening", car.seat_hardening, "0 here: the exact solution is that of the linear car")
    m3 = np.asarray(m3, dtype=np.float64)
    road_of = np.asarray(road_of, dtype=np.int64)
    n = len(m3)
    car = seat_car(car, n, c3, k3)
    c3s, k3s = np.broadcast_to(car.c3, (n,)), np.broadcast_to(car.k3, (n,))
    t = dt * np.arange(n_steps)
    arg = np.outer(omegas, t)
    # Im(c e^{j Omega t}) = Re(c) sin(Omega t) + Im(c) cos(Omega t): one real matrix product over (sin; cos)
    basis = np.concatenate([np.sin(arg), np.cos(arg)])  # (2 waves, steps), shared by every recording
    b = np.zeros(6)
    b[2] = car.k1 / car.m1
    seat, body = np.empty((n, n_steps)), np.empty((n, n_steps))
    for lo in range(0, n, CHUNK):
        rows = slice(lo, min(lo + CHUNK, n))
        a = np.stack(
            [replace(car, c3=c, k3=k).system_matrix(m) for c, k, m in zip(c3s[rows], k3s[rows], m3[rows])]
        )  # (r, 6, 6)
        # (j Omega_i I - A)^{-1} b for every recording and wave, weighted by the road's A_i e^{-j phi_i}
        resolvent = 1j * omegas[None, :, None, None] * np.eye(6) - a[:, None]
        x = np.linalg.solve(resolvent, np.broadcast_to(b, resolvent.shape[:-1])[..., None])[..., 0]  # (r, waves, 6)
        x = x * (amplitudes[road_of[rows]] * np.exp(-1j * phases[road_of[rows]]))[..., None]
        out = (a[:, :2] @ x.transpose(0, 2, 1)).reshape(-1, len(omegas))  # (r * 2, waves): complex amplitudes
        steady = (np.concatenate([out.real, out.imag], axis=1) @ basis).reshape(-1, 2, n_steps)
        # the transient e^{A t_k} (-rho_p(0)), stepped with the exact one-step map
        step_map = expm(a * dt)
        state = -x.sum(axis=1).imag  # (r, 6)
        transient = np.empty((state.shape[0], 2, n_steps))
        for k in range(n_steps):
            transient[:, :, k] = np.einsum("rij,rj->ri", a[:, :2], state)
            state = np.einsum("rij,rj->ri", step_map, state)
        acc = steady + transient
        seat[rows], body[rows] = acc[:, 0], acc[:, 1]
    return seat, body
