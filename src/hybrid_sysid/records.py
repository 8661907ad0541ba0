"""The self-describing run record: metrics.json (DESIGN.md's schema), curves.csv, predictions.csv."""

from __future__ import annotations

import json
import os
from pathlib import Path

RECORD = "metrics.json"


def write_json_atomic(path: Path, payload: dict) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(payload, indent=2) + "\n")
    os.replace(tmp, path)


def run_record(status: str, overrides: list[str], seed: int, steps: int = 0, train_seconds: float = 0.0,
               results: list[dict] | None = None, error: str | None = None, **extra) -> dict:
    return {"status": status, "error": error, "overrides": list(overrides), "seed": seed, "steps": steps,
            "train_seconds": round(train_seconds, 2), "results": results or [], **extra}


def read_record(run_dir: Path) -> dict:
    return json.loads((Path(run_dir) / RECORD).read_text())
