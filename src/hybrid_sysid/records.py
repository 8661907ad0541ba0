"""The self-describing run record, metrics.json (its fields: docs/design.md, \"Run records\")."""

from __future__ import annotations

import json
from pathlib import Path

from hybrid_sysid.files import write_atomic

RECORD = "metrics.json"


def write_json_atomic(path: Path, payload: dict) -> None:
    write_atomic(path, lambda tmp: tmp.write_text(json.dumps(payload, indent=2) + "\n"))


def write_yaml_atomic(path: Path, payload) -> None:
    import yaml

    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, lambda tmp: tmp.write_text(yaml.safe_dump(payload, sort_keys=False)))


def run_record(status: str, overrides: list[str], seed: int, steps: int = 0, train_seconds: float = 0.0,
               results: list[dict] | None = None, error: str | None = None, **extra) -> dict:
    return {"status": status, "error": error, "overrides": list(overrides), "seed": seed, "steps": steps,
            "train_seconds": round(train_seconds, 2), "results": results or [], **extra}


def read_record(run_dir: Path) -> dict:
    return json.loads((Path(run_dir) / RECORD).read_text())
