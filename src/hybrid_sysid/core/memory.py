"""The memory a process may still use: every limit it lives under, read from /proc and the cgroup tree (the
config's bound on a simulated dataset, config.memory, and the readers of recordings and windows check against it)."""

from __future__ import annotations

import os
from pathlib import Path

try:
    import resource
except ImportError:  # not on Windows, which has no RLIMIT_AS
    resource = None


PROC, CGROUP = Path("/proc"), Path("/sys/fs/cgroup")
UNLIMITED = 2**60  # cgroup v1 writes "no limit" as a huge number (9223372036854771712 on 4 KiB pages)
FREE, ADDRESS_SPACE, CGROUP_V2, CGROUP_V1 = (
    "free memory (MemAvailable)",
    "the address-space limit (RLIMIT_AS, ulimit -v) less the address space in use",
    "the cgroup's memory.max less memory.current",
    "the cgroup's memory.limit_in_bytes less memory.usage_in_bytes",
)


def memory_limits(proc: Path = PROC, cgroup: Path = CGROUP) -> dict[str, int]:
    """Bytes this process may still allocate under each limit it lives under that can be read, by name: the
    kernel's MemAvailable; the soft RLIMIT_AS less the address space already mapped (VmSize), which is what
    ``ulimit -v`` bounds, free memory or not; and the memory cgroup's limit less its usage, v2 and v1, at the
    process's own cgroup and each one above it (a container's or a cluster job's limit may sit on any).

    Parameters
    ----------
    proc, cgroup : pathlib.Path
        The roots read (the real ``/proc`` and cgroup file system by default).

    Returns
    -------
    dict of str to int
        Bytes by limit's name; a limit that cannot be read is left out (counts as none).
    """
    found = {}
    meminfo = _read(proc / "meminfo")
    for line in (meminfo or "").splitlines():
        if line.startswith("MemAvailable:"):
            found[FREE] = _kib(line)
    if meminfo is None:
        try:
            found[FREE] = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (OSError, ValueError, AttributeError):
            pass
    soft = resource.getrlimit(resource.RLIMIT_AS)[0] if resource is not None else None
    if soft is not None and soft != resource.RLIM_INFINITY:
        status = _read(proc / "self" / "status") or ""
        used = next((_kib(ln) for ln in status.splitlines() if ln.startswith("VmSize:")), 0)
        found[ADDRESS_SPACE] = max(0, soft - (used or 0))
    paths = _cgroup_paths(_read(proc / "self" / "cgroup") or "")
    v2_root = cgroup if (cgroup / "cgroup.controllers").is_file() else cgroup / "unified"
    for name, root, own, files in (
        (CGROUP_V2, v2_root, paths.get(""), ("memory.max", "memory.current")),
        (CGROUP_V1, cgroup / "memory", paths.get("memory"), ("memory.limit_in_bytes", "memory.usage_in_bytes")),
    ):
        left = [x for d in _up_from(root, own) if (x := _left(d, *files)) is not None]
        if left:
            found[name] = max(0, min(left))
    return {k: v for k, v in found.items() if v is not None}


def tightest_memory(proc: Path = PROC, cgroup: Path = CGROUP) -> tuple[int, str] | None:
    """(bytes, which limit) of the smallest of memory_limits; None where none can be read."""
    limits = memory_limits(proc, cgroup)
    return min(((v, k) for k, v in limits.items()), default=None)


def available_memory() -> int | None:
    """Bytes of memory this process may still use: the smallest of memory_limits (free memory, the address-space
    limit, the cgroup's limit); None where none can be read."""
    tightest = tightest_memory()
    return None if tightest is None else tightest[0]


def _read(path: Path) -> str | None:
    try:
        return path.read_text()
    except (OSError, UnicodeDecodeError):
        return None


def _kib(line: str) -> int | None:
    """The value of a /proc line such as "MemAvailable:  123 kB", in bytes."""
    try:
        return int(line.split()[1]) * 1024
    except (IndexError, ValueError):
        return None


def _cgroup_paths(text: str) -> dict[str, str]:
    """/proc/self/cgroup's lines "id:controllers:path" -> {controller: path}; "" for the v2 hierarchy."""
    paths = {}
    for line in text.splitlines():
        parts = line.split(":", 2)
        if len(parts) == 3:
            for controller in parts[1].split(",") if parts[1] else [""]:
                paths[controller] = parts[2]
    return paths


def _up_from(root: Path, own: str | None) -> list[Path]:
    """The process's cgroup directory under ``root`` and each one above it up to ``root``; the path may not exist
    under a container's own view of the hierarchy, whose root is then its cgroup."""
    dirs = [root]
    for part in Path((own or "/").lstrip("/")).parts:
        if part == "..":  # a cgroup namespace's view of a cgroup outside it: not under this mount
            break
        dirs.append(dirs[-1] / part)
    return [d for d in dirs if d.is_dir()]


def _left(folder: Path, limit_file: str, usage_file: str) -> int | None:
    """limit - usage in one cgroup directory; None where it sets no limit or cannot be read."""
    limit, usage = _read(folder / limit_file), _read(folder / usage_file)
    try:
        if limit is None or limit.strip() == "max" or int(limit) >= UNLIMITED:
            return None
        return int(limit) - int(usage or 0)
    except ValueError:
        return None
