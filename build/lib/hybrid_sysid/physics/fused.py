"""The dataset's hot loop compiled with numba: simulate eq. 11, record, and re-integrate in one pass.

Recordings are independent, so the kernel steps LANES of them side by side: the loop over lanes is the
innermost, and LLVM turns it into SIMD arithmetic across recordings (one recording's step is a chain of ~20
dependent operations, so stepping recordings one at a time leaves the cores waiting on latency). Results
are gathered per tile of STEPS steps in a small buffer laid out (channel, step, lane), then written to the
recording-major dataset eight steps at a time (column_store). Blocks of lanes run in parallel (prange).
Arithmetic follows ``simulate`` and ``relative_states`` operation by operation (no fused multiply-add;
running sums in np.cumsum's order, then the same multiplication by dt), so results equal the numpy path
exactly in float64 and to its float32 cast; tests/physics/test_fused.py checks both.
Measured against the previous kernel (two recordings per iteration, scalar) in benchmarks/kernel_anatomy.py.
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.quarter_car import QuarterCar

try:
    import numba

    from hybrid_sysid.physics.column_store import WIDTH, store_column8
except ImportError:  # pragma: no cover - numba is a dependency; keep the numpy path usable without it
    numba = None

LANES = 16  # recordings stepped together: four AVX2 vectors of float64, enough to hide the chain's latency
STEPS = 128  # steps per tile: the tile buffer (4 channels x STEPS x LANES) stays in the L1 cache


def _njit(**options):
    """numba.njit (lazy: compiled at the first call, then cached on disk), or nothing without numba."""
    return (lambda f: f) if numba is None else numba.njit(cache=True, fastmath=False, **options)


@_njit(parallel=True)
def _kernel(roads, road_of, p1s, p2s, dt, coef, consistent, seat_out, body_out, vel_out, disp_out):
    n_rec, n_steps = seat_out.shape
    a_uu, a_uv, a_uy, a_ux, a_ur = coef[0], coef[1], coef[2], coef[3], coef[4]
    b_vw, b_vv, b_vu, b_vz, b_vy, b_vx, c2m2 = coef[5], coef[6], coef[7], coef[8], coef[9], coef[10], coef[11]
    for block in numba.prange((n_rec + LANES - 1) // LANES):
        first = block * LANES
        n_lanes = min(LANES, n_rec - first)
        # one 2-D state array, not ten 1-D ones: more separate arrays exceed LLVM's budget of runtime alias
        # checks and the lane loop stays scalar. Rows: u v w x y z, seat - body running sums, p1 p2.
        state = np.zeros((10, LANES))
        lane_road = np.empty(LANES, np.int64)
        for lane in range(LANES):
            i = first + min(lane, n_lanes - 1)  # spare lanes of a last partial block repeat its last recording
            lane_road[lane] = road_of[i]
            state[8, lane], state[9, lane] = p1s[i], p2s[i]
        road_tile = np.empty((STEPS, LANES))
        tile = np.empty((4, STEPS, LANES), seat_out.dtype)  # the output dtype: cast once, in the SIMD loop
        for t0 in range(0, n_steps, STEPS):
            n_t = min(STEPS, n_steps - t0)
            for lane in range(LANES):
                road = roads[lane_road[lane]]
                for k in range(n_t):
                    road_tile[k, lane] = road[t0 + k]
            for k in range(n_t):
                r_k = road_tile[k]
                for lane in range(LANES):  # vectorised across recordings
                    u, v, w = state[0, lane], state[1, lane], state[2, lane]
                    x, y, z = state[3, lane], state[4, lane], state[5, lane]
                    s_rel, q_rel, p1, p2 = state[6, lane], state[7, lane], state[8, lane], state[9, lane]
                    seat12 = -p1 * (w - v) - p2 * (z - y)  # eq. 12-13 from the states at step k
                    body12 = b_vw * (w - v) + c2m2 * (u - v) + b_vz * (z - y) + b_vx * (x - y)
                    acc_u = a_uu * u + a_uv * v + a_uy * y + a_ux * x + a_ur * r_k[lane]
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
                    # re-integration (integrate): vel_k = dt * sum_{j<k} acc_j, pos_k = dt * sum_{j<=k} vel_j,
                    # of seat - body
                    vel_rel = s_rel * dt
                    q_rel += vel_rel
                    # relative_states' consistent pairing: z'_k with y'_{k+1} = y'_k + dt y''_k
                    vel_rel = vel_rel - dt * body if consistent else vel_rel
                    s_rel += seat - body
                    state[0, lane], state[1, lane], state[2, lane] = u, v, w
                    state[3, lane], state[4, lane], state[5, lane] = x, y, z
                    state[6, lane], state[7, lane] = s_rel, q_rel
                    tile[0, k, lane], tile[1, k, lane] = seat, body
                    tile[2, k, lane], tile[3, k, lane] = vel_rel, q_rel * dt
            n_vec = n_t - n_t % WIDTH
            for lane in range(n_lanes):
                i = first + lane
                for k in range(0, n_vec, WIDTH):
                    store_column8(seat_out, i, t0 + k, tile, 0, k, lane)
                    store_column8(body_out, i, t0 + k, tile, 1, k, lane)
                    store_column8(vel_out, i, t0 + k, tile, 2, k, lane)
                    store_column8(disp_out, i, t0 + k, tile, 3, k, lane)
                for k in range(n_vec, n_t):
                    seat_out[i, t0 + k], body_out[i, t0 + k] = tile[0, k, lane], tile[1, k, lane]
                    vel_out[i, t0 + k], disp_out[i, t0 + k] = tile[2, k, lane], tile[3, k, lane]


def _compiled_kernel():
    return _kernel


def available() -> bool:
    return numba is not None


def simulate_recordings(roads: np.ndarray, road_of: np.ndarray, m3: np.ndarray, dt: float,
                        car: QuarterCar = QuarterCar(), measurement: str = "consistent", out=None):
    """Every recording i on road ``roads[road_of[i]]`` with mass ``m3[i]``.

    Returns float32 (seat_acc, body_acc, rel_vel, rel_disp), each (n_recordings, n_steps); ``out`` may pass
    four preallocated C-contiguous arrays to fill, all float32 or all float64.
    """
    if measurement not in ("paper", "consistent"):
        raise ValueError(f"measurement = {measurement!r} is unknown; allowed: paper, consistent")
    roads = np.ascontiguousarray(roads, dtype=np.float64)
    p1, p2 = car.parameters(np.asarray(m3, dtype=np.float64))
    n, n_steps = len(p1), roads.shape[1]
    if out is None:
        out = tuple(np.empty((n, n_steps), dtype=np.float32) for _ in range(4))
    out = tuple(out)
    if (len(out) != 4 or any(a.dtype not in (np.float32, np.float64) or a.dtype != out[0].dtype
                             or a.shape != (n, n_steps) or not a.flags.c_contiguous for a in out)):
        raise ValueError(f"out must be four C-contiguous float32 or float64 arrays of one dtype, shape "
                         f"({n}, {n_steps}); got {[(a.dtype.name, a.shape) for a in out]}")
    coef = np.array([-car.c2 / car.m1, car.c2 / car.m1, car.k2 / car.m1, -(car.k1 + car.k2) / car.m1,
                     car.k1 / car.m1, car.c3 / car.m2, -(car.c2 + car.c3) / car.m2, car.c2 / car.m2,
                     car.k3 / car.m2, -(car.k2 + car.k3) / car.m2, car.k2 / car.m2, car.c2 / car.m2])
    _compiled_kernel()(roads, np.asarray(road_of, dtype=np.int64), np.ascontiguousarray(p1),
                       np.ascontiguousarray(p2), float(dt), coef, measurement == "consistent", *out)
    return out
