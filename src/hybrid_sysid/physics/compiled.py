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

from hybrid_sysid.core.checks import bad, check_choice
from hybrid_sysid.core.options import DEFAULT_MEASUREMENT, STEPPED
from hybrid_sysid.physics.quarter_car import Coefficients, QuarterCar, seat_car, step

step_inline = numba.njit(inline="always")(step)

# Recordings stepped side by side in one thread, as a loop over lanes that LLVM turns into SIMD instructions
# (four float64 lanes per instruction on AVX2 and AVX-512 alike). One recording's step is a chain of ~20
# dependent operations: four vectors' worth of independent chains keep the core busy while each chain waits.
# With 4 or 8 lanes the compiler unrolls the loop instead and it stays scalar. 16 is the fastest count measured
# (benchmarks/README.md, "Dataset generation").
LANES = 16
# Time steps staged per block on their way to the outputs: the stepping is lane-major and the outputs are
# recording-major, so each block transposes through a small buffer. 128 steps: 32 KB of float32 outputs and 16 KB
# of road, about an L1, and each output row written 512 bytes at a time; the fastest size measured into fresh
# arrays, as generate_dataset writes (benchmarks/README.md, "Dataset generation").
CHUNK = 128


@numba.njit(fastmath=False)
def simulate_block(
    roads, road_of, p1s, p2s, dt, coefs, consistent, kappa, seat_out, body_out, vel_out, disp_out, first
):
    """Recordings first .. first + LANES - 1 (spare lanes past the last recording repeat it, unwritten).

    A function of its own: written inline in the prange body, the same loop over lanes compiles to scalar code.
    The lane loop reads and writes only arrays allocated here, in lane-contiguous rows, which the compiler can
    vectorise and keep apart from the caller's arrays; row and column offsets stay non-negative (views of the
    chunk, ranges from 0), so no index needs Python's negative-index correction.
    """
    n_rec, n_steps = seat_out.shape
    c = np.empty((13, LANES))  # rows: the car's coefficients (Coefficients' order), p1, p2
    for lane in range(LANES):
        i = min(first + lane, n_rec - 1)
        for q in range(11):  # element by element: a slice assignment here doubles the compile time
            c[q, lane] = coefs[i, q]
        c[11, lane], c[12, lane] = p1s[i], p2s[i]
    # rows: u, v, w, x, y, z, then the running sums of seat - body and of the relative velocity
    s = np.zeros((8, LANES))
    road = np.empty((CHUNK, LANES))
    staged = np.empty((4, CHUNK, LANES), seat_out.dtype)
    for k0 in range(0, n_steps, CHUNK):
        m = min(CHUNK, n_steps - k0)
        for lane in range(LANES):
            src = roads[road_of[min(first + lane, n_rec - 1)], k0 : k0 + m]
            for j in range(m):
                road[j, lane] = src[j]
        for j in range(m):
            for lane in range(LANES):
                coef = Coefficients(
                    c[0, lane],
                    c[1, lane],
                    c[2, lane],
                    c[3, lane],
                    c[4, lane],
                    c[5, lane],
                    c[6, lane],
                    c[7, lane],
                    c[8, lane],
                    c[9, lane],
                    c[10, lane],
                )
                u, v, w, x, y, z, seat, body = step_inline(
                    s[0, lane],
                    s[1, lane],
                    s[2, lane],
                    s[3, lane],
                    s[4, lane],
                    s[5, lane],
                    road[j, lane],
                    c[11, lane],
                    c[12, lane],
                    dt,
                    coef,
                    consistent,
                    kappa,
                )
                s[0, lane], s[1, lane], s[2, lane], s[3, lane], s[4, lane], s[5, lane] = u, v, w, x, y, z
                rel_vel = s[6, lane] * dt
                s[7, lane] += rel_vel
                if consistent:  # relative_states' pairing: z'_k with y'_{k+1} = y'_k + dt y''_k
                    rel_vel = rel_vel - dt * body
                s[6, lane] += seat - body
                staged[0, j, lane], staged[1, j, lane] = seat, body
                staged[2, j, lane], staged[3, j, lane] = rel_vel, s[7, lane] * dt
        for lane in range(min(LANES, n_rec - first)):
            for q, out in enumerate((seat_out, body_out, vel_out, disp_out)):
                dst = out[first + lane, k0 : k0 + m]
                for j in range(m):
                    dst[j] = staged[q, j, lane]


@numba.njit(parallel=True, fastmath=False)
def kernel(roads, road_of, p1s, p2s, dt, coefs, consistent, kappa, seat_out, body_out, vel_out, disp_out):
    """Recording i: road ``roads[road_of[i]]``, parameters ``p1s[i], p2s[i]``, the car's coefficients
    ``coefs[i]`` (a row of Coefficients: the body row holds C3 and K3, which may differ per recording), the seat
    spring's hardening ``kappa`` (one for all); blocks of LANES run in parallel."""
    for block in numba.prange((seat_out.shape[0] + LANES - 1) // LANES):
        simulate_block(
            roads, road_of, p1s, p2s, dt, coefs, consistent, kappa, seat_out, body_out, vel_out, disp_out, block * LANES
        )


def car_arguments(road_of, m3, dt: float, car: QuarterCar, measurement: str, c3=None, k3=None) -> tuple:
    """The kernels' arguments after the roads, for recording i on road ``road_of[i]`` with mass ``m3[i]``:
    road_of, p1s, p2s, dt, the car's coefficients per recording, consistent, kappa."""
    check_choice("measurement", measurement, STEPPED)  # continuous recordings come from physics.exact
    m3 = np.asarray(m3, dtype=np.float64)
    car = seat_car(car, len(m3), c3, k3)
    p1, p2 = (np.broadcast_to(p, m3.shape) for p in car.parameters(m3))
    coefs = np.ascontiguousarray(np.stack(np.broadcast_arrays(*car.coefficients(), p1), axis=1)[:, :-1])
    return (
        np.asarray(road_of, dtype=np.int64),
        np.ascontiguousarray(p1),
        np.ascontiguousarray(p2),
        float(dt),
        coefs,
        measurement == "consistent",
        float(car.seat_hardening),
    )


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
    roads = np.ascontiguousarray(roads, dtype=np.float64)
    arguments = car_arguments(road_of, m3, dt, car, measurement, c3, k3)
    n, n_steps = len(arguments[1]), roads.shape[1]
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
        bad(
            "out",
            [(a.dtype.name, a.shape) for a in out],
            f"four C-contiguous float32 or float64 arrays of one dtype, shape ({n}, {n_steps})",
        )
    kernel(roads, *arguments, *out)
    return out
