"""The self-describing run record, metrics.json (its fields: docs/design.md, "Run records"): what it holds, and
that a completed one is never replaced."""

from __future__ import annotations


class CompletedRecordError(RuntimeError):
    """Writing would replace the record of a completed run."""


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


def is_completed(record) -> bool:
    return isinstance(record, dict) and record.get("status") == "completed"
