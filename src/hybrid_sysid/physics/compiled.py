"""The dataset's hot loop compiled with numba: eq. 11, the recording and the re-integration in one pass.

Not imported by ``hybrid_sysid.physics``, which stays plain numpy; ``hybrid_sysid.data`` imports it.
The step is ``quarter_car.step`` itself, compiled inline; the re-integration follows ``relative_states``
operation by operation (running sums in np.cumsum's order, then the same multiplication by dt), and no fused
multiply-add is allowed, so results equal the numpy path exactly in float64 and equal its float32 cast
(tests/physics/test_compiled.py checks both).
Compiled at the first call in a process, not cached on disk: numba's cache does not notice a change to
``quarter_car.step``, which lives in another file, and would then keep running the old step.
"""

from __future__ import annotations

import numba
import numpy as np

from hybrid_sysid.physics.quarter_car import (
    DEFAULT_MEASUREMENT,
    Coefficients,
    QuarterCar,
    check_measurement,
    seat_car,
    step,
)

step_inline = numba.njit(inline="always")(step)

# Recordings stepped side by side in one thread. One recording's step is a chain of ~20 dependent operations;
# with a few independent chains the core works on one while the others wait: twice as fast as one recording
# at a time, and 8 or 16 are no faster (benchmarks/README.md, "Dataset generation").
LANES = 4


@numba.njit(parallel=True, fastmath=False)
def kernel(roads, road_of, p1s, p2s, dt, coefs, consistent, seat_out, body_out, vel_out, disp_out):
    """Recording i: road ``roads[road_of[i]]``, parameters ``p1s[i], p2s[i]``, the car's coefficients
    ``coefs[i]`` (a row of Coefficients: the body row holds C3 and K3, which may differ per recording); blocks of
    LANES run in parallel."""
    n_rec, n_steps = seat_out.shape
    for block in numba.prange((n_rec + LANES - 1) // LANES):
        first = block * LANES
        # rows: u, v, w, x, y, z, then the running sums of seat - body and of the relative velocity
        s = np.zeros((8, LANES))
        for k in range(n_steps):
            # always LANES lanes (spare ones in the last block repeat its last recording): a fixed count compiles
            # to faster code than stopping at the last recording
            for lane in range(LANES):
                i = min(first + lane, n_rec - 1)
                c = coefs[i]
                coef = Coefficients(c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10])
                u, v, w, x, y, z, seat, body = step_inline(
                    s[0, lane],
                    s[1, lane],
                    s[2, lane],
                    s[3, lane],
                    s[4, lane],
                    s[5, lane],
                    roads[road_of[i], k],
                    p1s[i],
                    p2s[i],
                    dt,
                    coef,
                    consistent,
                )
                s[0, lane], s[1, lane], s[2, lane], s[3, lane], s[4, lane], s[5, lane] = u, v, w, x, y, z
                rel_vel = s[6, lane] * dt
                s[7, lane] += rel_vel
                if consistent:  # relative_states' pairing: z'_k with y'_{k+1} = y'_k + dt y''_k
                    rel_vel = rel_vel - dt * body
                s[6, lane] += seat - body
                seat_out[i, k], body_out[i, k] = seat, body
                vel_out[i, k], disp_out[i, k] = rel_vel, s[7, lane] * dt


def simulate_recordings(
    roads: np.ndarray,
    road_of,
    m3,
    dt: float,
    car: QuarterCar = QuarterCar(),
    measurement: str = DEFAULT_MEASUREMENT,
    out=None,
    c3=None,
    k3=None,
):
    """Every recording i on road ``roads[road_of[i]]`` with mass ``m3[i]``, from a zero state.

    ``c3``, ``k3``: per-recording seat constants (arrays of n_recordings) in place of the car's.

    Returns (seat_acc, body_acc, rel_vel, rel_disp), each (n_recordings, n_steps): what ``simulate`` followed
    by ``relative_states`` gives, in float32 unless ``out`` passes four C-contiguous arrays to fill, all
    float32 or all float64.
    """
    check_measurement(measurement)
    roads = np.ascontiguousarray(roads, dtype=np.float64)
    m3 = np.asarray(m3, dtype=np.float64)
    car = seat_car(car, len(m3), c3, k3)
    p1, p2 = (np.broadcast_to(p, m3.shape) for p in car.parameters(m3))
    n, n_steps = len(p1), roads.shape[1]
    if out is None:
        out = tuple(np.empty((n, n_steps), dtype=np.float32) for _ in range(4))
    out = tuple(out)
    if len(out) != 4 or any(
        a.dtype not in (np.float32, np.float64)
        or a.dtype != out[0].dtype
        or a.shape != (n, n_steps)
        or not a.flags.c_contiguous
        for a in out
    ):
        raise ValueError(
            f"out must be four C-contiguous float32 or float64 arrays of one dtype, shape "
            f"({n}, {n_steps}); got {[(a.dtype.name, a.shape) for a in out]}"
        )
    if measurement not in ("paper", "consistent"):
        raise ValueError(
            f"measurement = {measurement!r}: the kernel steps eq. 11 (paper, consistent); "
            "continuous recordings come from physics.exact"
        )
    coefs = np.ascontiguousarray(np.stack(np.broadcast_arrays(*car.coefficients(), p1), axis=1)[:, :-1])
    kernel(
        roads,
        np.asarray(road_of, dtype=np.int64),
        np.ascontiguousarray(p1),
        np.ascontiguousarray(p2),
        float(dt),
        coefs,
        measurement == "consistent",
        *out,
    )
    return out
