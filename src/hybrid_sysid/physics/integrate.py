"""The paper's re-integration of recorded accelerations (sec. 3, below eq. 21)."""

from __future__ import annotations

import numpy as np

from hybrid_sysid.core.checks import check_dt
from hybrid_sysid.core.options import DEFAULT_MEASUREMENT
from hybrid_sysid.physics.quarter_car import check_measurement


def integrate(acc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Symplectic Euler from a zero state along the last axis: v_k = v_{k-1} + dt a_{k-1}, x_k = x_{k-1} + dt v_k.

    Returns float64 (velocity, position), each the shape of ``acc``. Integrate once per whole recording
    from t0: a window integrated on its own would start from unknown velocity and position.
    """
    check_dt(dt)
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
    check_dt(dt)
    vel = _trapezoid(np.asarray(acc, dtype=np.float64), dt)
    return vel, _trapezoid(vel, dt)


def _trapezoid(x: np.ndarray, dt: float) -> np.ndarray:
    """The running trapezoid integral of float64 ``x`` along the last axis, 0 at the first sample."""
    out = np.zeros_like(x)
    np.cumsum(x[..., :-1] + x[..., 1:], axis=-1, out=out[..., 1:])
    out *= dt / 2
    return out


def correct_gain(x: np.ndarray) -> np.ndarray:
    """The 3-tap filter [-1/12, 7/6, -1/12] along the last axis, x_k - (x_{k-1} - 2 x_k + x_{k+1}) / 12; the
    first and last samples stay as they are (float64, a new array).

    Why: on samples of a sinusoid at theta = omega dt rad per sample the trapezoid rule integrates with the
    real gain (theta / 2) cot(theta / 2) = 1 - theta^2 / 12 - theta^4 / 720 - ... (no phase error), whose
    shortfall grows with frequency: -0.5% at 5.5 Hz, -2.4% at 12 Hz and -6.5% at 20 Hz for the double integral
    at dt = 5 ms. This filter's gain is 7/6 - cos(theta) / 6 = 1 + theta^2 / 12 - theta^4 / 144 + ..., so a
    corrected integral has the gain 1 - 11 theta^4 / 720 + ...: fourth order (the double integral's shortfall
    at 5.5, 12 and 20 Hz becomes -0.003%, -0.06% and -0.5%). Written with the second
    difference, it returns constants and ramps unchanged (to rounding, even on a large offset), so a state
    carried into a window keeps its constant-plus-ramp form. An edge sample has a neighbour on one side only;
    leaving it uncorrected is the filter with the missing neighbour extrapolated linearly.

    Parameters
    ----------
    x : array_like
        An integral sampled along its last axis (the trapezoid rule's output).

    Returns
    -------
    numpy.ndarray
        float64, a new array of ``x``'s shape.
    """
    x = np.asarray(x, dtype=np.float64)
    out = x.copy()
    out[..., 1:-1] -= (x[..., :-2] - 2 * x[..., 1:-1] + x[..., 2:]) / 12
    return out


def integrate_corrected(acc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The trapezoid rule from a zero state with each integral's gain corrected (``correct_gain``): velocity
    F(T(acc)), position F(T(velocity)), T the running trapezoid integral and F the 3-tap correction.

    Fourth order in the interior for samples of a smooth signal, where ``integrate_trapezoid`` is second order.
    The position integrates the corrected velocity and is corrected once more, so each integral is the same
    operation (velocity and position stay an integral pair, and each correction leaves one edge sample at
    each end). Integrating the uncorrected velocity and correcting the position twice has the same response in
    the interior but a 5-sample footprint; correcting the position only once leaves it second order (a gain
    of 1 - theta^2 / 12).

    What no correction here removes: the error the first sample leaves (Euler-Maclaurin's end term at t0;
    ``correct_gain`` supplies the one at t_k). A slope a'(0) != 0 leaves -dt^2 / 12 a'(0), a constant in the
    velocity and a ramp in the position, and a(0) != 0 a constant -dt^2 / 12 a(0) in the position. The exact
    recordings start at rest with a(0) = 0 but a'(0) != 0 (the road's step at t0 reaches the body through the
    wheel's damper), so their unfiltered regressors keep that constant and ramp; a band-pass of zero DC and
    ramp gain removes both.
    """
    check_dt(dt)
    vel = correct_gain(_trapezoid(np.asarray(acc, dtype=np.float64), dt))
    return vel, correct_gain(_trapezoid(vel, dt))


def relative_states(
    seat_acc: np.ndarray, body_acc: np.ndarray, dt: float, measurement: str = DEFAULT_MEASUREMENT
) -> tuple[np.ndarray, np.ndarray]:
    """Seat-minus-body relative velocity and displacement re-integrated from t0 (float64).

    These are the regressors of the hybrid objective, z''_k = -p1 rel_vel_k - p2 rel_disp_k.

    measurement "paper": eq. 22 as written, rel_vel_k = z'_k - y'_k.
    measurement "consistent": the pairing the simulator's seat update used, rel_vel_k = z'_k - y'_{k+1}
    (eq. 11 updates w with v_{k+1}); with the consistent recording the seat equation then holds exactly, while
    pairing z'_k with y'_k would leave a bias of about dt p1 y''_k (1.2% in p at dt = 1 ms, 6% at 5 ms).
    measurement "continuous": samples of the true motion, with rel_vel_k = z'_k - y'_k, integrated by the
    trapezoid rule with its gain corrected to fourth order (``integrate_corrected``). The plain trapezoid rule
    shrinks each integral of a frequency f by about (2 pi f dt)^2 / 12, twice as much in rel_disp as in rel_vel
    and more at high f, and a fit of the seat equation takes that up as too large a p: +0.2-0.3% on p1 and
    +0.3-0.5% on p2 by least squares on band-passed 500-step windows at dt = 5 ms, where the corrected
    regressors leave under 0.004% (tests/physics/test_integrator_gain.py).

    Parameters
    ----------
    seat_acc, body_acc : array_like
        Seat z'' and body y'' in m/s^2, the same shape, time along the last axis.
    dt : float
        The sampling interval in s.
    measurement : {"paper", "consistent", "continuous"}
        How the accelerations were recorded (``data.measurement``).

    Returns
    -------
    rel_vel, rel_disp : numpy.ndarray
        float64 arrays of the input's shape, in m/s and m.

    Raises
    ------
    ConfigError
        ``measurement`` not one of the three.
    """
    check_measurement(measurement)
    if measurement == "continuous":
        return integrate_corrected(np.asarray(seat_acc, dtype=np.float64) - np.asarray(body_acc, dtype=np.float64), dt)
    body_acc = np.asarray(body_acc, dtype=np.float64)
    # Integrate the difference, not each channel: seat and body positions follow the road (and drift) by far
    # more than their difference, so subtracting two integrated positions cancels most digits (the relative
    # displacement lost ~1e-12 of its size that way). Integration is linear, so the result is the same.
    rel_vel, rel_disp = integrate(np.asarray(seat_acc, dtype=np.float64) - body_acc, dt)
    if measurement == "consistent":
        rel_vel -= dt * body_acc
    return rel_vel, rel_disp
