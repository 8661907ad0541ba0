"""The self-describing run record, metrics.json (its fields: docs/design.md, \"Run records\")."""

from __future__ import annotations

import json
import logging
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
