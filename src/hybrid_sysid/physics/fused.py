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


def _njit(**options):
    """numba.njit (lazy: compiled at the first call, then cached on disk), or nothing without numba."""
    return (lambda f: f) if numba is None else numba.njit(cache=True, fastmath=False, **options)


@_njit()
def _step(state, r, p1, p2, dt, coef, consistent):
    """One eq.-11 step of one recording plus its re-integration; returns (state, seat, body, rel_vel, rel_disp).

    Both recordings (eq. 12 from the states at step k, or the applied accelerations) are computed and one is
    selected, so the step has no branch and the compiler can interleave two recordings' steps freely.
    """
    a_uu, a_uv, a_uy, a_ux, a_ur, b_vw, b_vv, b_vu, b_vz, b_vy, b_vx, c2m2 = coef
    u, v, w, x, y, z, s_rel, q_rel = state
    seat12 = -p1 * (w - v) - p2 * (z - y)  # eq. 12-13 from the states at step k
    body12 = b_vw * (w - v) + c2m2 * (u - v) + b_vz * (z - y) + b_vx * (x - y)
    acc_u = a_uu * u + a_uv * v + a_uy * y + a_ux * x + a_ur * r
    u = u + dt * acc_u
    acc_v = b_vw * w + b_vv * v + b_vu * u + b_vz * z + b_vy * y + b_vx * x
    v = v + dt * acc_v
    acc_w = -p1 * (w - v) - p2 * (z - y)
    w = w + dt * acc_w
    x = x + dt * u
    y = y + dt * v
    z = z + dt * w
    seat = acc_w if consistent else seat12
    body = acc_v if consistent else body12
    # re-integration (integrate): vel_k = dt * sum_{j<k} acc_j, pos_k = dt * sum_{j<=k} vel_j, of seat - body
    vel_rel = s_rel * dt
    q_rel += vel_rel
    # relative_states' consistent pairing: z'_k with y'_{k+1} = y'_k + dt y''_k
    vel_rel = vel_rel - dt * body if consistent else vel_rel
    s_rel += seat - body
    return (u, v, w, x, y, z, s_rel, q_rel), seat, body, vel_rel, q_rel * dt


@_njit(parallel=True)
def _kernel(roads, road_of, p1s, p2s, dt, coef, consistent, seat_out, body_out, vel_out, disp_out):
    # Two recordings per loop iteration: one recording's step is a chain of dependent multiply-adds, so a
    # second independent chain fills the idle cycles (1.5x faster than one recording at a time; more lanes
    # ran out of registers and were slower).
    n_rec, n_steps = seat_out.shape
    c = (coef[0], coef[1], coef[2], coef[3], coef[4], coef[5], coef[6], coef[7], coef[8], coef[9], coef[10],
         coef[11])
    for pair in numba.prange((n_rec + 1) // 2):
        i = 2 * pair
        j = min(i + 1, n_rec - 1)  # an odd last recording is computed twice, with identical results
        road_i, road_j = roads[road_of[i]], roads[road_of[j]]
        p1_i, p2_i, p1_j, p2_j = p1s[i], p2s[i], p1s[j], p2s[j]
        state_i = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        state_j = state_i
        for k in range(n_steps):
            state_i, seat, body, vel, disp = _step(state_i, road_i[k], p1_i, p2_i, dt, c, consistent)
            seat_out[i, k], body_out[i, k], vel_out[i, k], disp_out[i, k] = seat, body, vel, disp
            state_j, seat, body, vel, disp = _step(state_j, road_j[k], p1_j, p2_j, dt, c, consistent)
            seat_out[j, k], body_out[j, k], vel_out[j, k], disp_out[j, k] = seat, body, vel, disp


def _compiled_kernel():
    return _kernel


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
