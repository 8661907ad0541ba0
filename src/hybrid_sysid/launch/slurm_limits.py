"""What a SLURM partition allows a job, and whether a sweep's request fits it; read from SLURM's own commands
(``scontrol show partition``, ``sinfo``, ``squeue``), parsed here from their text so the tests feed real output.

A request above the partition would wait in the queue for ever (Reason=PartitionConfig), or sbatch would refuse
it with a traceback: ``too_big`` turns it into one line naming the key, the request and the limit, before
anything is submitted. A job that is queued all the same and then pends for a reason that never
clears (``never_starts``) gets the same kind of line while the sweep waits.
"""

from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass

from hybrid_sysid.core.checks import ConfigError

# pending reasons that no other job's end can clear: the request itself is outside what the partition,
# account or QOS allows (squeue(1), "JOB REASON CODES")
NEVER = (
    "PartitionConfig",
    "PartitionNodeLimit",
    "PartitionTimeLimit",
    "BadConstraints",
    "InvalidAccount",
    "InvalidQOS",
    "MaxMemPerLimit",
    "QOSMaxCpuPerJobLimit",
    "QOSMaxMemoryPerJob",
    "QOSMaxWallDurationPerJobLimit",
)
ENDED = ("BOOT_FAIL", "CANCELLED", "COMPLETED", "DEADLINE", "FAILED", "NODE_FAIL", "OUT_OF_MEMORY", "TIMEOUT")
UNLIMITED = ("UNLIMITED", "INFINITE", "NONE", "N/A", "")


@dataclass(frozen=True)
class Request:
    """One job's request, as hydra.launcher asks it."""

    cpus_per_task: int
    mem_gb: float | None
    minutes: int
    nodes: int = 1
    tasks_per_node: int = 1

    @property
    def cpus(self) -> int:  # a node's
        return self.cpus_per_task * self.tasks_per_node

    @property
    def mem_mb(self) -> int | None:
        return None if self.mem_gb is None else int(self.mem_gb * 1024)

    def text(self) -> str:
        mem = f" and {self.mem_gb:g} GB" if self.mem_gb else ""
        return f"{self.cpus} CPUs{mem} a node, {self.minutes} min, {self.nodes} node{'s' if self.nodes > 1 else ''}"


@dataclass(frozen=True)
class Limits:
    """What one job of a partition may have: a node's CPUs and memory (the largest node's, capped by the
    partition's MaxCPUsPerNode and MaxMemPerNode), its minutes and nodes. None: no limit."""

    name: str
    cpus: int | None
    mem_mb: int | None
    minutes: int | None
    nodes: int | None

    def text(self) -> str:
        cpus = "unlimited CPUs" if self.cpus is None else f"{self.cpus} CPUs"
        mem = "unlimited memory" if self.mem_mb is None else f"{self.mem_mb / 1024:.3g} GB"
        time = "no time limit" if self.minutes is None else f"{self.minutes} min"
        nodes = "any number of nodes" if self.nodes is None else f"{self.nodes} node{'s' if self.nodes > 1 else ''}"
        return f"partition {self.name} allows {cpus} and {mem} a node, {time}, {nodes} a job"


def minutes(text: str) -> int | None:
    """A SLURM time (``minutes``, ``minutes:seconds``, ``hours:minutes:seconds``, ``days-hours``,
    ``days-hours:minutes``, ``days-hours:minutes:seconds``) in whole minutes, rounded up; None when unlimited."""
    text = text.strip()
    if text.upper() in UNLIMITED:
        return None
    days, _, clock = text.rpartition("-")
    parts = [int(p) for p in clock.split(":")]
    if days:  # days-hours[:minutes[:seconds]]
        parts += [0] * (3 - len(parts))
        h, m, s = parts
        h += 24 * int(days)
    elif len(parts) == 3:
        h, m, s = parts
    elif len(parts) == 2:
        h, (m, s) = 0, parts
    else:
        h, m, s = 0, parts[0], 0
    return h * 60 + m + (1 if s else 0)


def _number(text: str | None) -> int | None:
    return None if text is None or text.upper() in UNLIMITED else int(re.match(r"\d+", text).group())


def partition_fields(scontrol_text: str) -> dict[str, str]:
    """``scontrol show partition NAME`` (one line with -o, or several) as its KEY=VALUE fields."""
    return dict(re.findall(r"(\w+)=(\S*)", scontrol_text))


def node_sizes(sinfo_text: str) -> tuple[int | None, int | None]:
    """The largest CPUs and memory (MB) of a node in ``sinfo -h -N -p NAME -o "%c %m"`` output."""
    rows = [line.split() for line in sinfo_text.splitlines() if line.split()]
    cpus = [int(r[0].rstrip("+")) for r in rows if r[0].rstrip("+").isdigit()]
    mems = [int(r[1].rstrip("+")) for r in rows if len(r) > 1 and r[1].rstrip("+").isdigit()]
    return (max(cpus) if cpus else None), (max(mems) if mems else None)


def limits(name: str, scontrol_text: str, sinfo_text: str) -> Limits:
    """A partition's limits from its scontrol line and its nodes' sinfo lines."""
    f = partition_fields(scontrol_text)
    node_cpus, node_mem = node_sizes(sinfo_text)
    cap_cpus, cap_mem = _number(f.get("MaxCPUsPerNode")), _number(f.get("MaxMemPerNode"))
    total_nodes, max_nodes = _number(f.get("TotalNodes")), _number(f.get("MaxNodes"))
    return Limits(
        name=f.get("PartitionName", name),
        cpus=min((v for v in (node_cpus, cap_cpus) if v is not None), default=None),
        mem_mb=min((v for v in (node_mem, cap_mem) if v is not None), default=None),
        minutes=minutes(f.get("MaxTime", "UNLIMITED")),
        nodes=min((v for v in (total_nodes, max_nodes) if v is not None), default=None),
    )


def too_big(request: Request, limit: Limits) -> ConfigError | None:
    """The refusal of the first of the request's keys above the partition's limit, naming the request and the
    limit; None if it fits."""
    checks = (
        ("hydra.launcher.cpus_per_task", request.cpus_per_task, request.cpus, limit.cpus, f"{request.cpus} CPUs"),
        ("hydra.launcher.mem_gb", request.mem_gb, request.mem_mb, limit.mem_mb, f"{request.mem_gb:g} GB a node"),
        ("hydra.launcher.timeout_min", request.minutes, request.minutes, limit.minutes, f"{request.minutes} min"),
        ("hydra.launcher.nodes", request.nodes, request.nodes, limit.nodes, f"{request.nodes} nodes"),
    )
    for key, value, asked, allowed, shown in checks:
        if asked is not None and allowed is not None and asked > allowed:
            follows = " (it follows trainer.threads)" if key.endswith("cpus_per_task") else ""
            return ConfigError(
                key,
                value,
                f"a job asks {shown}, but {limit.text()}, so it would never start; lower it{follows} or choose "
                "another hydra.launcher.partition",
            )
    return None


def queue(squeue_text: str) -> dict[str, tuple[str, str]]:
    """``squeue -h -r -t all -j ARRAY -o "%i|%T|%r"`` as {array task id ("12_0"): (state, reason)}."""
    found = {}
    for line in squeue_text.splitlines():
        parts = line.strip().split("|")
        if len(parts) == 3:
            found[parts[0]] = (parts[1], parts[2])
    return found


def never_starts(states: dict[str, tuple[str, str]]) -> str | None:
    """The reason a pending job of the queue can never start (NEVER), None if none pends for one."""
    for state, reason in states.values():
        if state == "PENDING" and reason in NEVER:
            return reason
    return None


def run(*command: str) -> str:
    """A SLURM command's standard output (it raises when the command fails or is missing)."""
    done = subprocess.run(command, capture_output=True, text=True, timeout=60, check=True)
    return done.stdout


def partition_limits(partition: str | None) -> Limits:
    """The limits of ``partition`` (the cluster's default one when None), from scontrol and sinfo."""
    if not partition:
        names = run("sinfo", "-h", "-o", "%P").split()
        partition = next((n.rstrip("*") for n in names if n.endswith("*")), names[0] if names else "")
    text = run("scontrol", "show", "partition", partition, "-o")
    return limits(partition, text, run("sinfo", "-h", "-N", "-p", partition, "-o", "%c %m"))
