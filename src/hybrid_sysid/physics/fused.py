"""The dataset's hot loop compiled with numba: simulate eq. 11, record, and re-integrate in one pass.

Each recording is independent, so recordings run in parallel (prange) and each one's time loop stays in
registers; the four float32 channels are written straight into the caller's arrays, so no float64
(recordings x steps) array is ever held. Arithmetic follows ``simulate`` and ``relative_states`` operation by
operation (running sums in the same order as np.cumsum, then the same multiplication by dt), so results agree
with the numpy path to rounding of the final float32 cast; tests/physics/test_fused.py checks this.
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.quarter_car import QuarterCar

try:
    import numba
except ImportError:  # pragma: no cover - numba is a dependency; keep the numpy path usable without it
    numba = None


def _kernel(roads, road_of, p1s, p2s, dt, coef, consistent, seat_out, body_out, vel_out, disp_out):
    a_uu, a_uv, a_uy, a_ux, a_ur, b_vw, b_vv, b_vu, b_vz, b_vy, b_vx, c2m2 = coef
    n_rec, n_steps = seat_out.shape
    for i in numba.prange(n_rec):
        road = roads[road_of[i]]
        p1, p2 = p1s[i], p2s[i]
        u = v = w = x = y = z = 0.0
        s_seat = s_body = 0.0  # running sums of the recorded accelerations (np.cumsum's order)
        q_seat = q_body = 0.0  # running sums of the re-integrated velocities
        for k in range(n_steps):
            if not consistent:  # eq. 12-13 from the states at step k
                seat = -p1 * (w - v) - p2 * (z - y)
                body = b_vw * (w - v) + c2m2 * (u - v) + b_vz * (z - y) + b_vx * (x - y)
            acc_u = a_uu * u + a_uv * v + a_uy * y + a_ux * x + a_ur * road[k]
            u = u + dt * acc_u
            acc_v = b_vw * w + b_vv * v + b_vu * u + b_vz * z + b_vy * y + b_vx * x
            v = v + dt * acc_v
            acc_w = -p1 * (w - v) - p2 * (z - y)
            w = w + dt * acc_w
            x = x + dt * u
            y = y + dt * v
            z = z + dt * w
            if consistent:
                seat = acc_w
                body = acc_v
            # re-integration (integrate): vel_k = dt * sum_{j<k} acc_j, pos_k = dt * sum_{j<=k} vel_j
            vel_seat = s_seat * dt
            vel_body = s_body * dt
            q_seat += vel_seat
            q_body += vel_body
            if consistent:  # relative_states pairs z'_k with y'_{k+1} = y'_k + dt y''_k
                vel_body = vel_body + dt * body
            seat_out[i, k] = seat
            body_out[i, k] = body
            vel_out[i, k] = vel_seat - vel_body
            disp_out[i, k] = q_seat * dt - q_body * dt
            s_seat += seat
            s_body += body


_compiled = None


def _compiled_kernel():
    global _compiled
    if _compiled is None:
        _compiled = numba.njit(parallel=True, cache=True, fastmath=False)(_kernel)
    return _compiled


def available() -> bool:
    return numba is not None


def simulate_recordings(roads: np.ndarray, road_of: np.ndarray, m3: np.ndarray, dt: float,
                        car: QuarterCar = QuarterCar(), measurement: str = "consistent", out=None):
    """Every recording i on road ``roads[road_of[i]]`` with mass ``m3[i]``.

    Returns float32 (seat_acc, body_acc, rel_vel, rel_disp), each (n_recordings, n_steps); ``out`` may pass
    four preallocated float32 arrays to fill.
    """
    if measurement not in ("paper", "consistent"):
        raise ValueError(f"measurement = {measurement!r} is unknown; allowed: paper, consistent")
    roads = np.ascontiguousarray(roads, dtype=np.float64)
    p1, p2 = car.parameters(np.asarray(m3, dtype=np.float64))
    n, n_steps = len(p1), roads.shape[1]
    if out is None:
        out = tuple(np.empty((n, n_steps), dtype=np.float32) for _ in range(4))
    coef = np.array([-car.c2 / car.m1, car.c2 / car.m1, car.k2 / car.m1, -(car.k1 + car.k2) / car.m1,
                     car.k1 / car.m1, car.c3 / car.m2, -(car.c2 + car.c3) / car.m2, car.c2 / car.m2,
                     car.k3 / car.m2, -(car.k2 + car.k3) / car.m2, car.k2 / car.m2, car.c2 / car.m2])
    _compiled_kernel()(roads, np.asarray(road_of, dtype=np.int64), np.ascontiguousarray(p1),
                       np.ascontiguousarray(p2), float(dt), coef, measurement == "consistent", *out)
    return out
