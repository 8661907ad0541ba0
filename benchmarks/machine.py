"""What the benchmarks print about the machine they ran on: its CPU (the name a run record stores) and its load,
since on shared virtual machines a timing depends on both more than on the code."""

from hybrid_sysid.runs.provenance import cpu_model


def cpu_name() -> str:
    return cpu_model() or "unknown CPU"


def load_average() -> str:
    """The 1-minute load average (/proc/loadavg), or "unknown" where there is none."""
    try:
        with open("/proc/loadavg") as f:
            return f.read().split()[0]
    except OSError:
        return "unknown"
