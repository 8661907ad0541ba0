"""The quarter-car model (eq. 7-10) and its semi-implicit Euler simulation (eq. 11-12)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MEASUREMENTS = ("paper", "consistent")


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

    def parameters(self, m3):
        """The unknowns (p1, p2) = (C3 / m3, K3 / m3); works on scalars and arrays alike."""
        m3 = np.asarray(m3, dtype=float)
        if np.any(m3 <= 0):
            raise ValueError(f"m3 must be > 0 kg, got min {m3.min()}")
        return self.c3 / m3, self.k3 / m3

    def system_matrix(self, m3: float) -> np.ndarray:
        """A of eq. 10 for the state (z', y', x', z, y, x); the road enters as f = (0, 0, K1 r / m1, 0, 0, 0)."""
        m1, m2 = self.m1, self.m2
        c2, c3, k1, k2, k3 = self.c2, self.c3, self.k1, self.k2, self.k3
        return np.array(
            [
                [-c3 / m3, c3 / m3, 0.0, -k3 / m3, k3 / m3, 0.0],
                [c3 / m2, -(c2 + c3) / m2, c2 / m2, k3 / m2, -(k2 + k3) / m2, k2 / m2],
                [0.0, c2 / m1, -c2 / m1, 0.0, k2 / m1, -(k1 + k2) / m1],
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
            ]
        )


def _step_matrix(car: QuarterCar, m3: float, dt: float) -> np.ndarray:
    """The linear map of one eq.-11 step on (w, v, u, z, y, x) with the road set to zero."""
    cols = []
    for e in np.eye(6):
        w, v, u, z, y, x = e
        u1 = u + dt * (car.c2 / car.m1 * (v - u) + car.k2 / car.m1 * y - (car.k1 + car.k2) / car.m1 * x)
        v1 = v + dt * (car.c3 / car.m2 * w - (car.c2 + car.c3) / car.m2 * v + car.c2 / car.m2 * u1
                       + car.k3 / car.m2 * z - (car.k2 + car.k3) / car.m2 * y + car.k2 / car.m2 * x)
        w1 = w + dt * (-car.c3 / m3 * (w - v1) - car.k3 / m3 * (z - y))
        cols.append([w1, v1, u1, z + dt * w1, y + dt * v1, x + dt * u1])
    return np.array(cols).T


def stable_dt_limit(car: QuarterCar = QuarterCar(), m3_min: float = 50.0, m3_max: float = 200.0) -> float:
    """Largest dt (s) for which the semi-implicit Euler step is stable (spectral radius <= 1) for m3 in range.

    The lightest seat is the stiffest mode; both ends are checked. Found by bisection on the exact step map.
    """
    def stable(dt: float) -> bool:
        return all(max(abs(np.linalg.eigvals(_step_matrix(car, m, dt)))) <= 1.0 + 1e-12 for m in (m3_min, m3_max))

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
    measurement: str = "paper",
    return_states: bool = False,
):
    """Simulate eq. 11 from a zero state and return the sensor channels (seat z'', body y'').

    road: (*road_batch, n_steps) road displacement r_k; m3: seat mass(es) broadcastable with road_batch
    (e.g. road (R, 1, N) with m3 (R, L) simulates every mass on every road). Returns two float64 arrays of
    shape (*batch, n_steps).

    measurement "paper" records eq. 12 from the states at step k. "consistent" records the accelerations
    the integrator applied, (w_{k+1} - w_k) / dt and (v_{k+1} - v_k) / dt, so that re-integrating them
    reproduces the simulated velocities and states exactly (see DESIGN.md on the hybrid objective's bias).

    return_states=True adds a third item: a dict of the states at steps 0..n_steps-1, keys "u", "v", "w"
    (wheel, body, seat velocity) and "x", "y", "z" (positions), for checks against other solvers.
    """
    if measurement not in MEASUREMENTS:
        raise ValueError(f"measurement = {measurement!r} is unknown; allowed: {', '.join(MEASUREMENTS)}")
    if not dt > 0:
        raise ValueError(f"dt = {dt} must be > 0")
    road = np.asarray(road, dtype=float)
    p1, p2 = car.parameters(m3)
    batch = np.broadcast_shapes(road.shape[:-1], np.shape(p1))
    n_steps = road.shape[-1]
    p1 = np.broadcast_to(p1, batch)
    p2 = np.broadcast_to(p2, batch)

    a_uu, a_uv, a_uy, a_ux, a_ur = (-car.c2 / car.m1, car.c2 / car.m1, car.k2 / car.m1,
                                    -(car.k1 + car.k2) / car.m1, car.k1 / car.m1)
    b_vw, b_vv, b_vu = car.c3 / car.m2, -(car.c2 + car.c3) / car.m2, car.c2 / car.m2
    b_vz, b_vy, b_vx = car.k3 / car.m2, -(car.k2 + car.k3) / car.m2, car.k2 / car.m2

    u, v, w, x, y, z = (np.zeros(batch) for _ in range(6))
    # time-major buffers: each step writes one contiguous row
    seat = np.empty((n_steps,) + batch)
    body = np.empty((n_steps,) + batch)
    consistent = measurement == "consistent"
    states = {key: np.empty((n_steps,) + batch) for key in "uvwxyz"} if return_states else None
    for k in range(n_steps):
        if states is not None:
            for key, val in zip("uvwxyz", (u, v, w, x, y, z)):
                states[key][k] = val
        r_k = road[..., k]
        if not consistent:  # eq. 12-13 from the states at step k
            seat[k] = -p1 * (w - v) - p2 * (z - y)
            body[k] = (b_vw * (w - v) + car.c2 / car.m2 * (u - v) + b_vz * (z - y) + b_vx * (x - y))
        acc_u = a_uu * u + a_uv * v + a_uy * y + a_ux * x + a_ur * r_k
        u = u + dt * acc_u
        acc_v = b_vw * w + b_vv * v + b_vu * u + b_vz * z + b_vy * y + b_vx * x
        v = v + dt * acc_v
        acc_w = -p1 * (w - v) - p2 * (z - y)
        w = w + dt * acc_w
        x = x + dt * u
        y = y + dt * v
        z = z + dt * w
        if consistent:
            seat[k] = acc_w
            body[k] = acc_v
    seat, body = np.moveaxis(seat, 0, -1), np.moveaxis(body, 0, -1)
    if states is None:
        return seat, body
    return seat, body, {key: np.moveaxis(val, 0, -1) for key, val in states.items()}
