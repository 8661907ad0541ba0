"""The config's bound on the dataset's size against the memory the process may still use (core.memory, whose
names are also read from here)."""

from __future__ import annotations

from hybrid_sysid.core.checks import bad
from hybrid_sysid.core.memory import (
    ADDRESS_SPACE,
    CGROUP_V1,
    CGROUP_V2,
    FREE,
    available_memory,
    memory_limits,
    tightest_memory,
)
from hybrid_sysid.data.spec import CHANNELS

__all__ = [
    "ADDRESS_SPACE",
    "CGROUP_V1",
    "CGROUP_V2",
    "FREE",
    "available_memory",
    "check_memory",
    "dataset_bytes",
    "memory_limits",
    "tightest_memory",
]


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
