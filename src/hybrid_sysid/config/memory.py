"""The memory a process may still use, and the config's bound on the dataset's size against it."""

from __future__ import annotations

import os
from pathlib import Path

from hybrid_sysid.core.checks import bad
from hybrid_sysid.data.dataset import CHANNELS


def available_memory() -> int | None:
    """Bytes of memory available to this process: the kernel's MemAvailable, capped by a cgroup (container,
    cluster job) limit; None where neither can be read."""
    found = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                found.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        try:
            found.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            pass
    try:
        cg = Path("/sys/fs/cgroup")
        limit = (cg / "memory.max").read_text().strip()
        if limit != "max":
            found.append(int(limit) - int((cg / "memory.current").read_text()))
    except (OSError, ValueError):
        pass
    return min(found) if found else None


def dataset_bytes(n_roads: int, n_masses: int, n_steps: int) -> int:
    """What a dataset needs in memory while it is simulated and stored: every channel of every recording at
    8 bytes (float32 channels, plus the copy that checksums or loads them) and the float64 road profiles
    (twice: the profile and the wave sum it is built from)."""
    return n_roads * n_masses * n_steps * len(CHANNELS) * 8 + 2 * n_roads * n_steps * 8


def check_memory(n_roads: int, n_masses: int, n_steps: int) -> None:
    """The dataset of data.n_roads x data.n_masses x data.n_steps fits in the memory available."""
    need, available = dataset_bytes(n_roads, n_masses, n_steps), available_memory()
    if available is not None and need > available:
        bad(
            "data.n_roads * data.n_masses * data.n_steps",
            f"{n_roads} * {n_masses} * {n_steps}",
            f"the dataset needs about {need / 2**30:.3g} GiB, more than the {available / 2**30:.3g} GiB of "
            "memory available",
        )
