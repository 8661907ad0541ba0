"""The hardening fix's displacement recursion compiled with numba (physics.faults.hardening, ``seat_displacement``).

``displacement_pass`` is ``numpy_pass`` with the same operations in the same order, window by window, so equal to
it bit for bit (tests/physics/test_compiled_hardening.py). The recursion is sequential in time, so numpy can only
vectorise it over windows: about thirty array operations on 64 numbers per sample, whose overhead took 40% of the
fix's fit of a training batch (benchmarks/README.md, "The fault fits"). Imported at the fix's first fit, not by
``hybrid_sysid.physics``; cached on disk, as the kernel reads nothing from another file.
"""

from __future__ import annotations

import numba
import numpy as np


def numpy_pass(d, free, rhs, alpha, beta, cubic, explicit, implicit, end):
    """Fill d[:, 1:end] and free[:, 1:end] from d[:, 0], free[:, 0]: the seat equation solved for d at each step
    by Newton from the linear spring's d, and free, d's sensitivity to d_0 (the reference the kernel equals)."""
    cubic3, explicit3 = 3.0 * cubic, 3.0 * explicit
    for k in range(1, end):
        last = d[:, k - 1]
        r = beta * last + rhs[:, k]
        if implicit < 1.0:
            r -= explicit * last * last * last
        x = r / alpha
        for _ in range(4):  # Newton from the linear spring's d: the cube is a correction
            x2 = x * x
            x -= (x * (alpha + cubic * x2) - r) / (alpha + cubic3 * x2)
        d[:, k] = x
        slope = beta - explicit3 * last * last if implicit < 1.0 else beta
        free[:, k] = free[:, k - 1] * slope / (alpha + cubic3 * x * x)


@numba.njit(fastmath=False, cache=True)
def displacement_pass(d, free, rhs, alpha, beta, cubic, explicit, implicit, end):
    """``numpy_pass`` compiled: one window at a time, each operation as numpy takes it (left to right)."""
    for i in range(d.shape[0]):
        a, b, c, e = alpha[i], beta[i], cubic[i], explicit[i]
        c3, e3 = 3.0 * c, 3.0 * e
        for k in range(1, end):
            last = d[i, k - 1]
            r = b * last + rhs[i, k]
            if implicit < 1.0:
                r -= e * last * last * last
            x = r / a
            for _ in range(4):
                x2 = x * x
                x -= (x * (a + c * x2) - r) / (a + c3 * x2)
            d[i, k] = x
            slope = b - e3 * last * last if implicit < 1.0 else b
            free[i, k] = free[i, k - 1] * slope / (a + c3 * x * x)


def run_pass(d, free, rhs, alpha, beta, cubic, explicit, implicit, end) -> None:
    """``displacement_pass`` on float64 arrays, each per-window constant as an (n,) array."""
    n = d.shape[0]
    per_window = [
        np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)))
        for v in (alpha, beta, cubic, explicit)
    ]
    displacement_pass(d, free, np.ascontiguousarray(rhs, dtype=np.float64), *per_window, float(implicit), int(end))
