"""The quarter-car model (eq. 7-10) and its semi-implicit Euler step (eq. 11) with the recorded accelerations.

Beyond the paper, the seat spring may harden (``seat_hardening`` kappa, 1/m^2): its force is K3 (d + kappa d^3),
d = z - y the seat-minus-body displacement, on the seat and, opposite, on the body. p2 = K3 / m3 stays the
small-amplitude stiffness, so a fit of the linear seat equation to such data reads a p2 too large. The
linear system (``system_matrix``, the stability limit, the exact solution of physics.exact) is that small-amplitude
car.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from hybrid_sysid.core.checks import bad, check_choice, check_dt
from hybrid_sysid.core.options import DEFAULT_MEASUREMENT, MEASUREMENTS, STEPPED

# What a recording holds as the two sensors' accelerations (core.options.MEASUREMENTS): "paper" is eq. 12 from the
# states at step k, "consistent" what the integrator applied. Re-integrating "paper" recordings does not give the
# simulated states back, which biases the hybrid objective (docs/discretisation.md, "The hybrid objective and the
# discretisation"). "continuous" samples the exact solution of eq. 10 every dt, as an accelerometer would
# (physics.exact): no discrete scheme reproduces it, so it is the honest target for a network trained on simulated
# data.


def check_measurement(measurement: str) -> None:
    check_choice("measurement", measurement, MEASUREMENTS)


class Coefficients(NamedTuple):
    """The car's entries of A (eq. 10) in the wheel and body rows, named by row and column:
    x'' = uu u + uv v + uy y + ux x + ur r and y'' = vw w + vv v + vu u + vz z + vy y + vx x."""

    uu: float  # -C2 / m1
    uv: float  # C2 / m1
    uy: float  # K2 / m1
    ux: float  # -(K1 + K2) / m1
    ur: float  # K1 / m1, the road's
    vw: float  # C3 / m2
    vv: float  # -(C2 + C3) / m2
    vu: float  # C2 / m2
    vz: float  # K3 / m2
    vy: float  # -(K2 + K3) / m2
    vx: float  # K2 / m2


@dataclass(frozen=True)
class QuarterCar:
    """Wheel (m1, state x), body (m2, y) and seat + passenger (m3, z), in SI units (paper, sec. 2.2)."""

    m1: float = 145.0
    m2: float = 2160.0
    k1: float = 40000.0
    k2: float = 149171.0
    k3: float = 98935.0
    c2: float = 4741.0
    c3: float = 615.0
    seat_hardening: float = 0.0  # kappa, 1/m^2: the seat spring's force K3 (d + kappa d^3); 0 is the linear spring

    def parameters(self, m3):
        """The unknowns (p1, p2) = (C3 / m3, K3 / m3) of eq. 15; works on scalars and arrays alike.

        Parameters
        ----------
        m3 : float or array_like
            Seat-plus-passenger mass in kg.

        Returns
        -------
        p1, p2 : float or numpy.ndarray
            In 1/s and 1/s^2, of ``m3``'s shape.

        Raises
        ------
        ConfigError
            A mass <= 0, naming ``m3``.
        """
        m3 = np.asarray(m3, dtype=float)
        if np.any(m3 <= 0):
            bad("m3", float(m3.min()), "masses > 0 kg")
        return self.c3 / m3, self.k3 / m3

    def describe(self) -> str:
        names = ("m1", "m2", "k1", "k2", "k3", "c2", "c3") + (("seat_hardening",) if self.seat_hardening else ())
        return ", ".join(f"{k}={getattr(self, k):g}" for k in names)

    def coefficients(self) -> Coefficients:
        m1, m2 = self.m1, self.m2
        return Coefficients(
            uu=-self.c2 / m1,
            uv=self.c2 / m1,
            uy=self.k2 / m1,
            ux=-(self.k1 + self.k2) / m1,
            ur=self.k1 / m1,
            vw=self.c3 / m2,
            vv=-(self.c2 + self.c3) / m2,
            vu=self.c2 / m2,
            vz=self.k3 / m2,
            vy=-(self.k2 + self.k3) / m2,
            vx=self.k2 / m2,
        )

    def system_matrix(self, m3: float) -> np.ndarray:
        """A of eq. 10 for the state (z', y', x', z, y, x); the road enters as f = (0, 0, K1 r / m1, 0, 0, 0).
        With a hardening seat spring, the car linearised at rest (its small-amplitude motion)."""
        c = self.coefficients()
        p1, p2 = self.parameters(m3)
        return np.array(
            [
                [-p1, p1, 0.0, -p2, p2, 0.0],
                [c.vw, c.vv, c.vu, c.vz, c.vy, c.vx],
                [0.0, c.uv, c.uu, 0.0, c.uy, c.ux],
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
            ]
        )


def step(u, v, w, x, y, z, r, p1, p2, dt, c: Coefficients, consistent: bool, kappa: float = 0.0):
    """One step of eq. 11 from step k to k + 1, and the two accelerations recorded for step k.

    Velocities u, v, w (wheel, body, seat) are updated in that order, each with the newest values, then the
    positions x, y, z; r is the road at step k. Works on scalars and on numpy arrays alike (arithmetic only),
    and is compiled as it stands for the dataset kernel (physics.compiled).
    Recorded (seat z'', body y''): with ``consistent`` the accelerations the step applied,
    (w_{k+1} - w_k) / dt and (v_{k+1} - v_k) / dt; otherwise eq. 12 from the states at step k.
    ``kappa`` (a scalar, 1/m^2): the seat spring's hardening, which adds K3 kappa (z - y)^3 to its force. At 0
    the linear step runs as it always has, operation for operation, so its results stay bit for bit.
    Returns (u, v, w, x, y, z) at step k + 1, then seat and body.
    """
    acc_u = c.uu * u + c.uv * v + c.uy * y + c.ux * x + c.ur * r
    u1 = u + dt * acc_u
    if kappa == 0.0:
        acc_v = c.vw * w + c.vv * v + c.vu * u1 + c.vz * z + c.vy * y + c.vx * x
        v1 = v + dt * acc_v
        acc_w = -p1 * (w - v1) - p2 * (z - y)
        d = cube = 0.0  # unused: typed alike in both branches for numba
    else:
        d = z - y
        cube = kappa * (d * d * d)  # the spring's force is K3 (d + cube); products round alike in numpy and numba
        acc_v = c.vw * w + c.vv * v + c.vu * u1 + c.vz * z + c.vy * y + c.vx * x + c.vz * cube
        v1 = v + dt * acc_v
        acc_w = -p1 * (w - v1) - p2 * (d + cube)
    w1 = w + dt * acc_w
    if consistent:
        seat, body = acc_w, acc_v
    elif kappa == 0.0:
        seat = -p1 * (w - v) - p2 * (z - y)
        body = c.vw * (w - v) + c.vu * (u - v) + c.vz * (z - y) + c.vx * (x - y)
    else:
        seat = -p1 * (w - v) - p2 * (d + cube)
        body = c.vw * (w - v) + c.vu * (u - v) + c.vz * (d + cube) + c.vx * (x - y)
    return u1, v1, w1, x + dt * u1, y + dt * v1, z + dt * w1, seat, body


def seat_car(car: QuarterCar, n: int, c3=None, k3=None) -> QuarterCar:
    """The car with per-recording seat constants: c3, k3 arrays of n values (None keeps the car's). A QuarterCar
    whose c3, k3 are arrays gives per-recording parameters and coefficients (arithmetic broadcasts), which
    ``simulate`` and ``step`` accept as they are."""
    values = {}
    for name, given in (("c3", c3), ("k3", k3)):
        if given is not None:
            given = np.asarray(given, dtype=float)
            if given.shape != (n,) or not np.all(given > 0):
                bad(name, f"an array of shape {given.shape}", f"{n} values > 0, one per recording")
            values[name] = given
    return replace(car, **values) if values else car


def _step_matrix(car: QuarterCar, m3: float, dt: float) -> np.ndarray:
    """The linear map of one eq.-11 step on (u, v, w, x, y, z) with the road at 0: column j is the image of e_j."""
    p1, p2 = car.parameters(m3)
    basis = np.eye(6)  # row i holds component i of every basis vector
    return np.array(step(*basis, 0.0, p1, p2, dt, car.coefficients(), True)[:6])


def stable_dt_limit(
    car: QuarterCar = QuarterCar(), m3_min: float = 50.0, m3_max: float = 200.0, seat_spread: float = 0.0
) -> float:
    """Largest dt (s) for which the semi-implicit Euler step is stable (spectral radius <= 1) for m3 in range
    and, with ``seat_spread`` s, C3 and K3 anywhere in car.c3 * [1 - s, 1 + s] and car.k3 * [1 - s, 1 + s].

    The lightest seat is the stiffest mode; every corner of the range is checked. Found by bisection on the exact
    step map. A hardening seat spring is stiffer at amplitude: the limit is that of its small-amplitude motion.

    Parameters
    ----------
    car : QuarterCar
        The car's constants (default: the paper's).
    m3_min, m3_max : float
        The seat mass range in kg.
    seat_spread : float
        The relative spread s of C3 and K3 (``data.seat_spread``).

    Returns
    -------
    float
        The limit in s: 0.03615 for the paper's car and 50-200 kg.
    """
    ends = (1.0 - seat_spread, 1.0 + seat_spread) if seat_spread else (1.0,)
    cars = [replace(car, c3=car.c3 * a, k3=car.k3 * b) for a in ends for b in ends]

    def stable(dt: float) -> bool:
        return all(
            max(abs(np.linalg.eigvals(_step_matrix(c, m, dt)))) <= 1.0 + 1e-12 for c in cars for m in (m3_min, m3_max)
        )

    lo, hi = 1e-5, 1e-5
    while stable(hi) and hi < 10.0:
        lo, hi = hi, hi * 2
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def simulate(
    road: np.ndarray,
    m3,
    dt: float,
    car: QuarterCar = QuarterCar(),
    measurement: str = DEFAULT_MEASUREMENT,
    return_states: bool = False,
):
    """Simulate eq. 11 from a zero state and return the sensor channels (seat z'', body y'').

    measurement "paper" records eq. 12 from the states at step k. "consistent" records the accelerations
    the integrator applied, (w_{k+1} - w_k) / dt and (v_{k+1} - v_k) / dt, so that re-integrating them
    reproduces the simulated velocities and states exactly (docs/discretisation.md, "The hybrid objective and the
    discretisation").

    Parameters
    ----------
    road : array_like
        (*road_batch, n_steps) road displacement r_k in m.
    m3 : float or array_like
        Seat mass(es) in kg, broadcastable with road_batch: road (R, 1, N) with m3 (R, L) simulates every mass on
        every road.
    dt : float
        The step in s.
    car : QuarterCar
        The car's constants.
    measurement : {"paper", "consistent"}
        The recording; continuous recordings come from ``physics.exact``.
    return_states : bool
        True adds a third item: a dict of the states at steps 0..n_steps-1, keys "u", "v", "w" (wheel, body,
        seat velocity) and "x", "y", "z" (positions), for checks against other solvers.

    Returns
    -------
    seat, body : numpy.ndarray
        float64 arrays of shape (*batch, n_steps), in m/s^2.

    Raises
    ------
    ConfigError
        An unknown ``measurement``, ``dt`` <= 0 or a mass <= 0.
    """
    check_choice("measurement", measurement, STEPPED)  # continuous recordings come from physics.exact
    check_dt(dt)
    road = np.asarray(road, dtype=float)
    p1, p2 = car.parameters(m3)
    batch = np.broadcast_shapes(road.shape[:-1], np.shape(p1))
    n_steps = road.shape[-1]
    p1 = np.broadcast_to(p1, batch)
    p2 = np.broadcast_to(p2, batch)
    coef = car.coefficients()
    consistent = measurement == "consistent"

    u, v, w, x, y, z = (np.zeros(batch) for _ in range(6))
    # time-major buffers: each step writes one contiguous row
    seat = np.empty((n_steps,) + batch)
    body = np.empty((n_steps,) + batch)
    states = np.empty((6, n_steps) + batch) if return_states else None
    for k in range(n_steps):
        if states is not None:
            states[:, k] = u, v, w, x, y, z
        u, v, w, x, y, z, seat[k], body[k] = step(
            u, v, w, x, y, z, road[..., k], p1, p2, dt, coef, consistent, car.seat_hardening
        )
    seat, body = np.moveaxis(seat, 0, -1), np.moveaxis(body, 0, -1)
    if states is None:
        return seat, body
    return seat, body, {key: np.moveaxis(val, 0, -1) for key, val in zip("uvwxyz", states)}
