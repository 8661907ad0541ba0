"""A sweep's console: a line at its start (how many jobs, how many at a time), then one line per finished job: its
number of the total, its swept values, its headline error (test split, the lowest noise level and K, p1 and p2),
its time, the sweep's elapsed time and an estimate of the time left (elapsed / done x remaining). The jobs count
themselves in the sweep directory's ``.progress`` (runs.layout.PROGRESS), one lock at a time, since parallel
workers print their own lines."""

from __future__ import annotations

import fcntl
import json
import math
import time
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf


def sweep_jobs(config: DictConfig) -> tuple[int | None, list[str]]:
    """The number of jobs of the sweep (None where it cannot be told) and the keys it sweeps: a search's
    n_trials and parameters, else the product of the command line's and hydra.sweeper.params' value lists."""
    sweeper = config.hydra.sweeper
    params = sweeper.get("params")
    params = OmegaConf.to_container(params) if isinstance(params, DictConfig) else dict(params or {})
    if sweeper.get("n_trials") is not None:  # a search (conf/hydra/sweeper/study.yaml)
        return int(sweeper.n_trials), list(params)
    try:
        from hydra.core.override_parser.overrides_parser import OverridesParser

        given = [f"{k}={v}" for k, v in params.items()] + list(config.hydra.overrides.task)
        sizes = {}
        for override in OverridesParser.create().parse_overrides(given):
            key = override.get_key_element()
            sizes[key] = len(list(override.sweep_string_iterator())) if override.is_sweep_override() else 1
    except Exception:  # noqa: BLE001 - e.g. a glob over a config group: no count, the lines say so
        return None, []
    return math.prod(sizes.values()), [k for k, n in sizes.items() if n > 1]


def start_line(config: DictConfig, jobs: int | None, sweep_dir: Path) -> str:
    """The sweep's first line: so the console is never silent while the first jobs train."""
    launcher = config.hydra.launcher
    at_once = launcher.get("n_jobs") if "joblib" in str(launcher.get("_target_", "")) else None
    if at_once is None and "BasicLauncher" in str(launcher.get("_target_", "")):
        at_once = 1
    threads = OmegaConf.select(config, "trainer.threads")
    parts = [f"{jobs} jobs" if jobs else "jobs"]
    if at_once:
        parts.append(f"{at_once} at a time")
    if threads:
        parts.append(f"{threads} torch thread{'s' * (threads != 1)} each")
    return (
        f"sweep: {', '.join(parts)} into {sweep_dir}; a line as each job ends (its messages: train.log in its "
        "directory), then the table"
    )


def count_done(path: Path, num) -> tuple[dict, int]:
    """Append job ``num`` to the progress file and return its header and how many jobs have ended (one lock:
    parallel workers count in turn)."""
    with open(path, "a+", encoding="utf-8") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            f.write(f"{num}\n")
            f.flush()
            f.seek(0)
            lines = f.read().splitlines()
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)
    header = json.loads(lines[0])
    if not isinstance(header, dict):
        raise ValueError(f"{path} has no header")
    return header, len(set(lines[1:]))


def _clock(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m}:{s:02d}"


def _short(value: str) -> str:
    try:
        number = float(value)
    except ValueError:
        return value
    return f"{number:.3g}" if len(value) > 8 else value


def job_line(header: dict, done: int, num, job_return: Any, seconds: float) -> str:
    """``[done/jobs] #num key=value ...: p1 .. %, p2 .. % (test, noise .., K=..) in .. s; sweep m:ss, about m:ss
    left``; a failed or interrupted job says so with its error."""
    jobs = header.get("jobs")
    overrides = dict(o.split("=", 1) for o in (getattr(job_return, "overrides", None) or []) if "=" in o)
    swept = header.get("swept") or [k for k in ("objective", "seed") if k in overrides]
    which = " ".join(f"{k}={_short(overrides[k])}" for k in swept if k in overrides)
    record = getattr(job_return, "return_value", None)
    if isinstance(record, BaseException):
        outcome = f"failed ({type(record).__name__}: {record})"
    elif not isinstance(record, dict):
        outcome = "ended"
    elif record.get("status", "completed") != "completed":
        outcome = f"{record['status']} ({record.get('error') or 'no error recorded'})"
    else:
        outcome = headline(record.get("results")) or "completed"
    elapsed = time.time() - float(header.get("start", time.time()))
    count = f"{done}/{jobs}" if jobs else str(done)
    left = ""
    if jobs and done < jobs:
        left = f", about {_clock(elapsed / done * (jobs - done))} left"
    outcome = outcome.splitlines()[0][:160]
    return f"[{count}] #{num} {which}: {outcome} in {seconds:.0f} s; sweep {_clock(elapsed)}{left}"


def headline(results) -> str | None:
    """A record's headline error: mean relative deviation of p1 and p2 on the test split, at its lowest noise
    level and K."""
    rows = [r for r in results or [] if r.get("split") == "test" and "mean_rel_dev" in r]
    if not rows:
        return None
    noise = min(r.get("noise_std", 0) for r in rows)
    k = min(r.get("windows", 1) for r in rows if r.get("noise_std", 0) == noise)
    first = [r for r in rows if r.get("noise_std", 0) == noise and r.get("windows", 1) == k]
    cells = {r["parameter"]: r["mean_rel_dev"] for r in first}
    text = ", ".join(f"{p} {100 * v:.2f} %" for p, v in sorted(cells.items()))
    return f"{text} (test, noise {noise:g}, K={k})"
