"""The memory that estimating K windows of many recordings takes, against what the process may still use (the
smallest of its limits: core.memory.memory_limits, the one home of that question)."""

from __future__ import annotations

from hybrid_sysid.core.memory import tightest_memory
from hybrid_sysid.inference.inputs import InputError

CHUNK = 4096  # windows per forward pass, so long recordings need bounded memory


def window_bytes(n_windows: int, window: int) -> int:
    """Bytes that n_windows windows of 2 x window steps take while they are estimated: float64 twice (each
    recording's cut windows and the stack of all of them), plus the float32 copy of one chunk."""
    return n_windows * 2 * window * 8 * 2 + min(n_windows, CHUNK) * 2 * window * 4


def max_windows(available: int, window: int) -> int:
    """The most windows whose window_bytes fit in ``available`` bytes."""
    per = 2 * window  # values per window
    n = available // (per * 20)  # up to CHUNK windows, each has its float32 copy
    return n if n < CHUNK else (available - CHUNK * per * 4) // (per * 16)


def check_window_memory(k: int, names: list, steps: list[int], window: int) -> None:
    """The windows of every recording, cut and stacked, fit in the memory available (window_bytes): the least of
    free memory, the address-space limit and the cgroup's, so the refusal comes before any allocation fails."""
    need, tightest = window_bytes(k * len(names), window), tightest_memory()
    if tightest is None or need <= tightest[0]:
        return
    available, limit = tightest
    fit = max_windows(available, window) // len(names)
    longest = max(range(len(steps)), key=steps.__getitem__)
    which = (
        f"recording {names[0]!r} ({steps[0]} steps)"
        if len(names) == 1
        else f"{len(names)} recordings (the longest, {names[longest]!r}, {steps[longest]} steps)"
    )
    raise InputError(
        "windows",
        k,
        (f"1 to {fit}" if fit >= 1 else "fewer recordings per call, or more memory")
        + f" for {which}: {k * len(names)} windows of 2 x {window} steps need {need / 2**30:.3g} GiB of memory "
        f"(float64, cut and stacked, plus a float32 copy of up to {CHUNK} windows) and {available / 2**30:.3g} GiB "
        f"is available ({limit})",
    )
