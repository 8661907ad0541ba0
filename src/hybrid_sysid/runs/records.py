"""The self-describing run record, metrics.json (its fields: docs/design.md, \"Run records\")."""

from __future__ import annotations

import json
import logging
import platform
from functools import lru_cache
from pathlib import Path

from hybrid_sysid.core.files import write_json_atomic

RECORD = "metrics.json"
log = logging.getLogger("hybrid_sysid")


class CompletedRecordError(RuntimeError):
    """Writing would replace the record of a completed run."""


def completed_record(run_dir: Path) -> dict | None:
    """The record in run_dir if it is readable and says completed, else None (missing, truncated, failed...)."""
    try:
        record = read_record(run_dir)
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("status") == "completed" else None


def write_record(run_dir: Path, record: dict) -> None:
    """Write run_dir/metrics.json atomically; never over a completed run's record (a run is final once done)."""
    if completed_record(run_dir) is not None:
        raise CompletedRecordError(f"{Path(run_dir) / RECORD} holds a completed run; not replacing it")
    write_json_atomic(Path(run_dir) / RECORD, record)


def run_record(
    status: str,
    overrides: list[str],
    seed: int,
    steps: int = 0,
    train_seconds: float = 0.0,
    results: list[dict] | None = None,
    error: str | None = None,
    **extra,
) -> dict:
    return {
        "status": status,
        "error": error,
        "overrides": list(overrides),
        "seed": seed,
        "steps": steps,
        "train_seconds": round(train_seconds, 2),
        "results": results or [],
        **extra,
    }


@lru_cache(maxsize=1)
def cpu_model() -> str | None:
    """The processor's model name, as /proc/cpuinfo's "model name" (Linux) or else platform.processor() gives it;
    None when neither names it. Recorded because the last digits of a run's numbers depend on the kind of CPU
    (docs/reliability.md); read once per process."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, sep, value = line.partition(":")
                if sep and key.strip() == "model name" and value.strip():
                    return " ".join(value.split())
    except OSError:  # not Linux
        pass
    return platform.processor().strip() or None


def read_record(run_dir: Path) -> dict:
    return json.loads((Path(run_dir) / RECORD).read_text())


def previous_record(run_dir: Path, overrides) -> dict | None:
    """The record of a run that already completed in this directory (a re-run sweep skips it), else None. A
    record that cannot be read (e.g. truncated) is no completed run: the job runs again."""
    run_dir = Path(run_dir)
    path = run_dir / RECORD
    record = completed_record(run_dir)
    if record is None:
        try:
            read_record(run_dir)
        except FileNotFoundError:
            pass
        except (OSError, ValueError) as exc:
            log.warning("%s is unreadable (%s); running the job again", path, exc)
        return None
    wanted = [o for o in overrides if not o.startswith("resume=")]
    had = [o for o in record.get("overrides", []) if not o.startswith("resume=")]
    if sorted(had) != sorted(wanted):
        raise ValueError(
            f"run directory {run_dir} holds a completed run of other overrides ({' '.join(had)}); "
            "choose another hydra.run.dir / hydra.sweep.dir"
        )
    return record
