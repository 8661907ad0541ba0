"""Fake run and sweep directories shaped like train.py's records (no training is run); imported by the tests,
so it is not a conftest (two conftest modules would shadow each other on sys.path)."""

import json
import re
import zlib
from itertools import dropwhile, takewhile
from pathlib import Path

import numpy as np

NOISES = [0.0, 0.003, 0.01, 0.1]
PARAMS = ["p1", "p2"]
OBJECTIVES = ["labelled", "hybrid"]
SEEDS = [0, 1]
FAILED_ERROR = "RuntimeError: loss is nan at step 120\nwhile training"


def _results(rng) -> list[dict]:
    evals = [("train", 0.0), ("val", 0.0)] + [("test", s) for s in NOISES]
    # random values with all their digits, so the summary must carry numbers exactly, not to a few decimals
    return [
        {
            "split": split,
            "noise_std": std,
            "parameter": p,
            "mean_rel_dev": float(rng.uniform(0.01, 0.4)),
            "std_rel_dev": float(rng.uniform(0.005, 0.2)),
            "n": 40,
        }
        for split, std in evals
        for p in PARAMS
    ]


def _curves(run_dir: Path, rng) -> None:
    lines = ["step,seconds,split,noise_std,parameter,mean_rel_dev,std_rel_dev,n"]
    for step in (100, 200, 300):
        for split, std in [("train", 0.0)] + [("test", s) for s in NOISES]:
            for p in PARAMS:
                lines.append(
                    f"{step},{step / 10},{split},{std},{p},{rng.uniform(0.01, 0.4) / step * 100},"
                    f"{rng.uniform(0.01, 0.1)},40"
                )
    (run_dir / "curves.csv").write_text("\n".join(lines) + "\n")


def known_results(values: dict, n: int = 40, std_rel_dev: float = 0.05) -> list[dict]:
    """Results rows with chosen numbers: values maps (split, noise_std, parameter) or (split, noise_std, windows,
    parameter) to mean_rel_dev; a 3-tuple key writes no "windows" field (as records before that field)."""
    rows = []
    for key, v in values.items():
        split, std, *k, p = key
        rows.append(
            {
                "split": split,
                "noise_std": std,
                **({"windows": k[0]} if k else {}),
                "parameter": p,
                "mean_rel_dev": float(v),
                "std_rel_dev": std_rel_dev,
                "n": n,
            }
        )
    return rows


def make_run(
    run_dir: Path,
    overrides: list[str],
    seed: int,
    status: str = "completed",
    error=None,
    corrupt: bool = False,
    hydra: bool = True,
    results: list[dict] | None = None,
    config: dict | None = None,
    steps: int = 300,
) -> Path:
    """A run directory; ``results`` replaces the random results, ``config`` is written as .hydra/config.yaml
    (with the objective and model choices from the overrides in .hydra/hydra.yaml)."""
    run_dir.mkdir(parents=True)
    rng = np.random.default_rng(zlib.crc32(f"{run_dir}".encode()))
    if hydra:  # Hydra writes this before the job runs
        (run_dir / ".hydra").mkdir()
        (run_dir / ".hydra" / "overrides.yaml").write_text("".join(f"- {o}\n" for o in overrides))
    if config is not None:
        import yaml

        (run_dir / ".hydra").mkdir(exist_ok=True)
        (run_dir / ".hydra" / "config.yaml").write_text(yaml.safe_dump(config))
        chosen = dict(o.split("=", 1) for o in overrides if "=" in o and "." not in o.split("=")[0])
        choices = {
            "objective": chosen.get("objective", "labelled"),
            "model": chosen.get("model", "paper_cnn"),
            "data": chosen.get("data", "paper"),
        }
        (run_dir / ".hydra" / "hydra.yaml").write_text(yaml.safe_dump({"hydra": {"runtime": {"choices": choices}}}))
    if corrupt:  # e.g. a job killed while a non-atomic writer was at work
        (run_dir / "metrics.json").write_text('{"status": "completed", "results": [{"split": "te')
        return run_dir
    completed = status == "completed"
    record = {
        "status": status,
        "error": error,
        "overrides": overrides,
        "seed": seed,
        "steps": steps if completed else 0,
        "train_seconds": 12.34 + seed if completed else 0.0,
        "results": (_results(rng) if results is None else results) if completed else [],
        "monitor": "val/rel_dev",
    }
    (run_dir / "metrics.json").write_text(json.dumps(record, indent=2))
    if completed:
        _curves(run_dir, rng)
        (run_dir / "predictions.csv").write_text("split,noise_std,p1_true,p1_pred\ntest,0.0,5.0,5.1\n")
    return run_dir


def make_sweep(sweep: Path, failed: bool = True, extra: tuple = ()) -> Path:
    """2 objectives x 2 seeds (jobs 0-3); with failed=True also a failed hybrid job (4) and a labelled job whose
    metrics.json is corrupt (5), as Hydra's multirun lays them out: SWEEP/<job number>/."""
    job = 0
    for objective in OBJECTIVES:
        for seed in SEEDS:
            make_run(sweep / str(job), [f"objective={objective}", f"seed={seed}", "noise=ladder", *extra], seed)
            job += 1
    if failed:
        make_run(
            sweep / "4", ["objective=hybrid", "seed=2", "noise=ladder", *extra], 2, status="failed", error=FAILED_ERROR
        )
        make_run(sweep / "5", ["objective=labelled", "seed=2", "noise=ladder", *extra], 2, corrupt=True)
    return sweep


def plain(cell: str) -> str:
    """A markdown cell without its marks and interval: "**m ± s** [a, b] †" -> "m ± s"."""
    return re.sub(r" \[[^\]]*\]$", "", cell.removesuffix(" †")).removeprefix("**").removesuffix("**")


def interval(cell: str) -> tuple[float, float] | None:
    """The "[a, b]" of a markdown cell as numbers, None if it has none."""
    m = re.search(r"\[(-?[\d.]+), (-?[\d.]+)\]", cell)
    return (float(m.group(1)), float(m.group(2))) if m else None


def parse_markdown(text: str) -> list[dict]:
    """The first markdown table in text as a list of {header: cell}."""
    lines = list(
        takewhile(lambda ln: ln.startswith("|"), dropwhile(lambda ln: not ln.startswith("|"), text.splitlines()))
    )
    split = [[c.strip() for c in re.split(r"(?<!\\)\|", ln.strip().strip("|"))] for ln in lines]
    return [dict(zip(split[0], row)) for row in split[2:]]
