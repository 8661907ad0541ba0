"""The paper's re-integration of recorded accelerations (sec. 3, below eq. 21)."""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.quarter_car import DEFAULT_MEASUREMENT, check_measurement


def integrate(acc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Symplectic Euler from a zero state along the last axis: v_k = v_{k-1} + dt a_{k-1}, x_k = x_{k-1} + dt v_k.

    Returns float64 (velocity, position), each the shape of ``acc``. Integrate once per whole recording
    from t0: a window integrated on its own would start from unknown velocity and position.
    """
    if not dt > 0:
        raise ValueError(f"dt = {dt} must be > 0")
    acc = np.asarray(acc, dtype=np.float64)
    vel = np.zeros_like(acc)
    np.cumsum(acc[..., :-1], axis=-1, out=vel[..., 1:])
    vel *= dt
    pos = np.cumsum(vel, axis=-1)
    pos *= dt
    return vel, pos


def integrate_trapezoid(acc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The trapezoid rule from a zero state: v_k = v_{k-1} + dt (a_{k-1} + a_k) / 2, x_k likewise from v.

    Second-order accurate for samples of a smooth signal, where symplectic Euler is first-order: the
    re-integration that suits recordings of continuous motion (measurement "continuous").
    """
    if not dt > 0:
        raise ValueError(f"dt = {dt} must be > 0")
    acc = np.asarray(acc, dtype=np.float64)
    vel = np.zeros_like(acc)
    np.cumsum(acc[..., :-1] + acc[..., 1:], axis=-1, out=vel[..., 1:])
    vel *= dt / 2
    pos = np.zeros_like(acc)
    np.cumsum(vel[..., :-1] + vel[..., 1:], axis=-1, out=pos[..., 1:])
    pos *= dt / 2
    return vel, pos


def relative_states(
    seat_acc: np.ndarray, body_acc: np.ndarray, dt: float, measurement: str = DEFAULT_MEASUREMENT
) -> tuple[np.ndarray, np.ndarray]:
    """Seat-minus-body relative velocity and displacement re-integrated from t0 (float64).

    These are the regressors of the hybrid objective, z''_k = -p1 rel_vel_k - p2 rel_disp_k.

    measurement "paper": eq. 22 as written, rel_vel_k = z'_k - y'_k.
    measurement "consistent": the pairing the simulator's seat update used, rel_vel_k = z'_k - y'_{k+1}
    (eq. 11 updates w with v_{k+1}); with the consistent recording the seat equation then holds exactly, while
    pairing z'_k with y'_k would leave a bias of about dt p1 y''_k (1.2% in p at dt = 1 ms, 6% at 5 ms).
    measurement "continuous": samples of the true motion, integrated by the trapezoid rule (second order), with
    rel_vel_k = z'_k - y'_k; the seat equation then holds up to the rule's O(dt^2) error.
    """
    check_measurement(measurement)
    if measurement == "continuous":
        return integrate_trapezoid(np.asarray(seat_acc, dtype=np.float64) - np.asarray(body_acc, dtype=np.float64), dt)
    body_acc = np.asarray(body_acc, dtype=np.float64)
    # Integrate the difference, not each channel: seat and body positions follow the road (and drift) by far
    # more than their difference, so subtracting two integrated positions cancels most digits (the relative
    # displacement lost ~1e-12 of its size that way). Integration is linear, so the result is the same.
    rel_vel, rel_disp = integrate(np.asarray(seat_acc, dtype=np.float64) - body_acc, dt)
    if measurement == "consistent":
        rel_vel -= dt * body_acc
    return rel_vel, rel_disp
