"""The sensor faults of physics.sensors compiled with numba, and the dataset kernel that records through them.

``apply_faults`` is ``physics.sensors.apply`` with the same operations in the same order, so equal to it bit for
bit. ``simulate_faulted`` simulates blocks of recordings in float64 (physics.compiled's ``simulate_block``), puts
each recording's faults on its two channels while they are in the cache, re-integrates them with
``relative_states``' arithmetic, and writes the four float32 channels once (tests/physics/test_sensors.py and
tests/data/test_sensor_faults.py check both against the numpy path). Doing all of it per block, rather than array
by array, keeps the faults' cost near the plain dataset's (benchmarks/README.md, "Sensor faults").
Like physics.compiled, imported only by hybrid_sysid.data and the tests.
"""

from __future__ import annotations

import numba
import numpy as np

from hybrid_sysid.core.checks import bad
from hybrid_sysid.physics.compiled import LANES, car_arguments, simulate_block
from hybrid_sysid.physics.sensors import FaultDraws, butterworth, delay_taps


@numba.njit(fastmath=False)
def _lowpass_row(x, b, a, out):
    """sensors.lowpass on one row (``out`` may be ``x``: each sample is read before it is written)."""
    b0, b1, b2, a1, a2 = b[0], b[1], b[2], a[1], a[2]
    z1 = 0.0
    z2 = 0.0
    for k in range(x.shape[0]):
        xk = x[k]
        yk = b0 * xk + z1
        z1 = b1 * xk - a1 * yk + z2
        z2 = b2 * xk - a2 * yk
        out[k] = yk


@numba.njit(fastmath=False)
def _delay_row(src, taps, out):
    """sensors.fractional_delay's sum on one row, tap by tap over the whole row as numpy sums it (the loop over
    time inside vectorises without reordering any sum)."""
    width = taps.shape[0]
    for k in range(out.shape[0]):
        out[k] = 0.0
    for q in range(width):
        h = taps[width - 1 - q]
        for k in range(out.shape[0]):
            out[k] += h * src[q + k]


@numba.njit(parallel=True, fastmath=False)
def _lowpass_rows(x, b, a, out):
    for i in numba.prange(x.shape[0]):
        _lowpass_row(x[i], b[i], a[i], out[i])


@numba.njit(parallel=True, fastmath=False)
def _delay_rows(padded, start, taps, out):
    for i in numba.prange(out.shape[0]):
        _delay_row(padded[i, start[i] :], taps[i], out[i])


def apply_faults(seat: np.ndarray, body: np.ndarray, draws: FaultDraws, dt: float, half_width: int = 32):
    """physics.sensors.apply, compiled: the faulted (seat, body), float64, equal to it bit for bit."""
    seat = np.ascontiguousarray(seat, dtype=np.float64)
    body = np.ascontiguousarray(body, dtype=np.float64)
    if draws.cutoffs is not None:
        filtered = []
        for j, x in enumerate((seat, body)):
            b, a = butterworth(draws.cutoffs[:, j], dt)
            filtered.append(np.empty_like(x))
            _lowpass_rows(x, b, a, filtered[-1])
        seat, body = filtered
    seat = draws.gains[:, :1] * seat
    body = draws.gains[:, 1:] * body
    if np.any(draws.skews != 0):
        whole, taps = delay_taps(draws.skews / dt, half_width)
        pad = half_width + int(np.abs(whole).max(initial=0))
        padded = np.pad(body, ((0, 0), (pad, pad)), mode="edge")
        body = np.empty_like(seat)
        _delay_rows(padded, pad - whole - half_width, taps, body)
    return seat, body


@numba.njit(fastmath=False)
def _record(seat, body, dt, consistent, seat_out, body_out, vel_out, disp_out):
    """One recording's channels and relative_states' re-integration of them (physics.compiled's running sums)."""
    vel_sum = 0.0
    disp_sum = 0.0
    for k in range(seat_out.shape[0]):
        s, b = seat[k], body[k]
        rel_vel = vel_sum * dt
        disp_sum += rel_vel
        if consistent:
            rel_vel = rel_vel - dt * b
        vel_sum += s - b
        seat_out[k], body_out[k] = s, b
        vel_out[k], disp_out[k] = rel_vel, disp_sum * dt


@numba.njit(fastmath=False)
def _filter_block(x, b, a, gains):
    """Each row of x (lanes, T) low-passed (``b``, ``a``: (lanes, 3), or no rows for none) and scaled by its gain,
    in place: the rows' recursions interleaved, a loop over lanes inside the loop over time, so that they run
    side by side instead of each waiting on its own previous sample."""
    m, length = x.shape
    if b.shape[0] == 0:
        for lane in range(m):
            for k in range(length):
                x[lane, k] = gains[lane] * x[lane, k]
        return
    c = np.empty((5, m))
    for lane in range(m):
        c[0, lane], c[1, lane], c[2, lane] = b[lane, 0], b[lane, 1], b[lane, 2]
        c[3, lane], c[4, lane] = a[lane, 1], a[lane, 2]
    z1 = np.zeros(m)
    z2 = np.zeros(m)
    for k in range(length):
        for lane in range(m):
            xk = x[lane, k]
            yk = c[0, lane] * xk + z1[lane]
            z1[lane] = c[1, lane] * xk - c[3, lane] * yk + z2[lane]
            z2[lane] = c[2, lane] * xk - c[4, lane] * yk
            x[lane, k] = gains[lane] * yk


@numba.njit(parallel=True, fastmath=False)
def _faulted_kernel(
    roads,
    road_of,
    p1s,
    p2s,
    dt,
    coefs,
    consistent,
    kappa,
    b,
    a,
    gains,
    starts,
    taps,
    front,
    seat_out,
    body_out,
    vel_out,
    disp_out,
):
    """Blocks of LANES recordings in parallel: simulated over the roads' length, each channel low-passed (when
    ``b`` has rows), scaled by its gain, the body delayed (when ``taps`` has rows) reading ``front`` samples of
    rest before t0, then recorded and re-integrated over out's length."""
    n, n_steps = seat_out.shape
    n_ext = roads.shape[1]
    for block in numba.prange((n + LANES - 1) // LANES):
        first = block * LANES
        m = min(LANES, n - first)
        seat, body = np.empty((m, n_ext)), np.empty((m, n_ext))
        unused = np.empty((m, n_ext))  # the clean states' rows, written over each other: a smaller block stays in cache
        end = first + m
        simulate_block(
            roads,
            road_of[first:end],
            p1s[first:end],
            p2s[first:end],
            dt,
            coefs[first:end],
            consistent,
            kappa,
            seat,
            body,
            unused,
            unused,
            0,
        )
        rest = np.zeros(front + n_ext)
        moved = np.empty(n_steps)
        for channel, x in enumerate((seat, body)):
            _filter_block(x, b[first:end, channel], a[first:end, channel], gains[first:end, channel])
        for lane in range(m):
            i = first + lane
            if taps.shape[0]:
                rest[front:] = body[lane]
                _delay_row(rest[starts[i] :], taps[i], moved)
                _record(seat[lane], moved, dt, consistent, seat_out[i], body_out[i], vel_out[i], disp_out[i])
            else:
                _record(seat[lane], body[lane], dt, consistent, seat_out[i], body_out[i], vel_out[i], disp_out[i])


def simulate_faulted(
    roads: np.ndarray,
    road_of,
    m3,
    dt: float,
    car,
    measurement: str,
    draws: FaultDraws,
    n_steps: int,
    front: int,
    half_width: int,
    c3=None,
    k3=None,
):
    """The four float32 channels (n_recordings, n_steps) of recordings through faulty sensors: what
    ``physics.compiled.simulate_recordings`` (over the roads' length, in float64), then ``sensors.apply`` on the
    channels preceded by ``front`` zeros, cropped to samples front .. front + n_steps - 1, then ``relative_states``
    give, cast to float32. The roads must run past n_steps by the delay's reach (data.dataset.skew_margin)."""
    roads = np.ascontiguousarray(roads, dtype=np.float64)
    arguments = car_arguments(road_of, m3, dt, car, measurement, c3, k3)
    n = len(arguments[1])
    if draws.cutoffs is None:
        b = a = np.empty((0, 2, 3))
    else:
        designs = [butterworth(draws.cutoffs[:, j], dt) for j in range(2)]  # seat, body: (b, a) of (n, 3) each
        b, a = (np.ascontiguousarray(np.stack([d[q] for d in designs], axis=1)) for q in range(2))
    if np.any(draws.skews != 0):
        whole, taps = delay_taps(draws.skews / dt, half_width)
        starts = front - whole - half_width
        reach = half_width + int(np.abs(whole).max())  # the kernel does not check its indices: this does
        if front < reach or roads.shape[1] < n_steps + reach:
            bad(
                "front", front, f">= {reach} zeros before t0 and roads of >= n_steps + {reach} steps: the delay's reach"
            )
    else:
        taps, starts = np.empty((0, 2 * half_width + 1)), np.zeros(n, dtype=np.int64)
    out = tuple(np.empty((n, n_steps), dtype=np.float32) for _ in range(4))
    gains = np.ascontiguousarray(draws.gains, dtype=np.float64)
    _faulted_kernel(roads, *arguments, b, a, gains, starts, np.ascontiguousarray(taps), front, *out)
    return out
