"""A sweep's console: a line at its start (how many jobs, how many at a time), then one line per finished job: its
number of the total, its swept values, its headline error (test split, the lowest noise level and K, p1 and p2),
its time, the sweep's elapsed time and an estimate of the time left (hybrid_sysid.launch.time_left). The jobs write
their starts and ends to the sweep directory's ``.progress`` (runs.layout.PROGRESS, written by runs.sweepdir), one
lock at a time, since parallel workers print their own lines: a JSON header, then one JSON line per event."""

from __future__ import annotations

import itertools
import math
import os
import time
from pathlib import Path
from typing import Any

from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.core.overrides import parse_override
from hybrid_sysid.core.words import count
from hybrid_sysid.launch.kinds_alike import DATA_KEYS
from hybrid_sysid.launch.time_left import estimate, rates_of, work_seconds
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.runs.sweepdir import SweepDir

MAX_KINDS = 100_000  # jobs: a longer sweep's header names no kinds (its estimate then treats jobs alike)


def _swept_values(config: DictConfig) -> dict[str, list[str]] | None:
    """key -> its values, in the order Hydra's basic sweeper takes them (hydra.sweeper.params, then the command
    line; a later value of a key replaces an earlier one), so that the product's i-th item is job i; None where it
    cannot be told (a glob over a config group)."""
    params = config.hydra.sweeper.get("params")
    params = OmegaConf.to_container(params) if isinstance(params, DictConfig) else dict(params or {})
    try:
        given = [f"{k}={v}" for k, v in params.items()] + list(config.hydra.overrides.task)
        values = {}
        for override in OverridesParser.create().parse_overrides(given):
            key = override.get_key_element()
            sweep = override.is_sweep_override()
            values[key] = list(override.sweep_string_iterator()) if sweep else [override.get_value_element_as_str()]
    except Exception:  # noqa: BLE001 - e.g. a glob over a config group: no count, the lines say so
        return None
    return values


def sweep_jobs(config: DictConfig) -> tuple[int | None, list[str]]:
    """The number of jobs of the sweep (None where it cannot be told) and the keys it sweeps: a search's
    n_trials and parameters, else the product of the command line's and hydra.sweeper.params' value lists."""
    sweeper = config.hydra.sweeper
    if sweeper.get("n_trials") is not None:  # a search (conf/hydra/sweeper/study.yaml)
        params = sweeper.get("params")
        return int(sweeper.n_trials), list(OmegaConf.to_container(params) if params is not None else {})
    values = _swept_values(config)
    if values is None:
        return None, []
    return math.prod(len(v) for v in values.values()), [k for k, v in values.items() if len(v) > 1]


def job_kinds(config: DictConfig) -> list[str] | None:
    """Each job's kind, by job number: its swept values but the seed (jobs of a kind take about as long); None for
    a search, whose trials are drawn as it goes."""
    if config.hydra.sweeper.get("n_trials") is not None:
        return None
    values = _swept_values(config)
    if values is None or math.prod(len(v) for v in values.values()) > MAX_KINDS:
        return None
    kinds = [i for i, (k, v) in enumerate(values.items()) if len(v) > 1 and k != "seed"]
    keys = list(values)
    return [" ".join(f"{keys[i]}={job[i]}" for i in kinds) for job in itertools.product(*values.values())]


def at_once(config: DictConfig, jobs: int | None = None) -> int | None:
    """How many jobs the launcher runs at a time: joblib's n_jobs (negative: counted back from the cores, as
    joblib does), 1 for the basic launcher; None where the launcher does not say (SLURM, submitit_local)."""
    launcher = config.hydra.launcher
    target = str(launcher.get("_target_", ""))
    if "joblib" in target:
        n = launcher.get("n_jobs")
        if not isinstance(n, int) or n == 0:
            return None
        n = n if n > 0 else max((os.cpu_count() or 1) + 1 + n, 1)
    elif "BasicLauncher" in target:
        n = 1
    else:
        return None
    return min(n, jobs) if jobs else n


def start_line(config: DictConfig, jobs: int | None, sweep_dir: Path) -> str:
    """The sweep's first lines: so the console is never silent while the first jobs train."""
    n = at_once(config)
    threads = OmegaConf.select(config, "trainer.threads")
    parts = [count(jobs, "job") if jobs else "jobs"]
    if n:
        parts.append(f"{n} at a time")
    if threads:
        parts.append(f"{count(threads, 'torch thread')} each")
    return (
        f"sweep: {', '.join(parts)} into {sweep_dir}\n"
        "a line as each job ends (its messages: train.log in its directory), then the table"
    )


def done_before(config: DictConfig, jobs: int | None) -> dict[str, float | None]:
    """Job number -> the work its record gives, for each job whose directory already holds a completed run (a
    sweep run again after an interruption): training.run skips it, so it ends at once and the estimate must not
    wait for it. Only where job directories are named by number, Hydra's default."""
    sweep = OmegaConf.to_container(config.hydra.sweep, resolve=False)
    sweep_dir = Path(str(config.hydra.sweep.dir))
    if sweep.get("subdir") != "${hydra.job.num}" or not jobs or not sweep_dir.is_dir():
        return {}
    out = {}
    for path in sweep_dir.iterdir():
        if path.name.isascii() and path.name.isdigit() and int(path.name) < jobs:  # not "²", which int refuses
            record = RunDir(path).completed_record()
            if record is not None:
                out[path.name] = work_seconds(record)
    return out


def header_of(config: DictConfig, start: float) -> dict:
    """The progress file's first line: what the job lines and the time-left estimate need from the sweep."""
    jobs, swept = sweep_jobs(config)
    return {
        "jobs": jobs,
        "swept": swept,
        "start": start,
        "at_once": at_once(config, jobs),
        "kinds": job_kinds(config),
        "done_before": done_before(config, jobs),
    }


def mark_start(sweep_dir: Path, num, now: float, pid: int | None = None) -> None:
    """Job ``num`` started at ``now`` in process ``pid``: the estimate counts what it still needs, not a job's whole
    time."""
    SweepDir(sweep_dir).add_progress({"start": num, "t": now, "pid": pid})


def count_done(sweep_dir: Path, num, entry: dict | None = None) -> tuple[dict, int]:
    """Append the end of job ``num`` (``entry``: its time, whether its worker was cold, its work; see time_left)
    to the sweep's progress file and return its header, with the file's events under "events", and how many jobs
    have ended."""
    header, events = SweepDir(sweep_dir).progress_with({**(entry or {}), "end": num})
    header["events"] = events
    return header, len({e["end"] for e in events if "end" in e})


STEP_LINE_AFTER = 30.0  # seconds: a job of a kind not timed yet that still needs this long says its time left


def mark_steps(sweep_dir: Path, num, given: list[str], done: int, total: int, start: float, now: float) -> str | None:
    """Job ``num`` (its override strings: ``given``; started at ``start``) did ``done`` of ``total`` steps. Returns a
    line when they time its kind first (no job of its kind ended, none said its steps, no other kind timed it) and
    the job still needs over STEP_LINE_AFTER seconds: the last job line said "at least", this one need not wait for
    an end."""
    sweep = SweepDir(sweep_dir)
    header, events = sweep.progress_with({"steps": num, "t": now, "done": done, "of": total})
    kinds = header.get("kinds") or []
    if not (isinstance(num, int) and 0 <= num < len(kinds)):
        return None
    mine = {n for n, k in enumerate(kinds) if k == kinds[num]}
    ended = len({e["end"] for e in events if "end" in e})
    if not ended or any(e.get("end") in mine or e.get("said") in mine for e in events):
        return None  # before the first end, no line guessed the kind; after one of its own, the lines time it
    guess = estimate(header, events, now)
    rate = rates_of(events).get(num)
    if guess is None or rate is None or rate[0] * (total - done) < STEP_LINE_AFTER:
        return None
    blind = estimate(header, [e for e in events if e.get("steps") not in mine], now)
    if blind is not None and blind[1] == guess[1]:  # its kind was timed already (by kinds that take as long)
        return None
    sweep.add_progress({"said": num, "t": now})
    seconds, untimed = guess
    left = f"{'at least' if untimed else 'about'} {_clock(seconds)} left"
    elapsed = _clock(now - float(header.get("start", now)))
    where = f"#{num} {_which(header, given)}: step {done} of {total} in {now - start:.0f} s"
    return f"[{ended}/{header['jobs']} ended] {where}; sweep {elapsed}, {left}"


def _clock(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m}:{s:02d}"


def _short(value: str) -> str:
    try:
        number = float(value)
    except ValueError:
        return value
    return f"{number:.3g}" if len(value) > 8 else value


def left_text(header: dict, done: int, now: float) -> str:
    """The job line's end: ", about m:ss left"; ", at least m:ss left" with how many jobs it could not time (of a
    kind with no ended job and no running job's steps); elapsed / done x remaining where no job's time is known
    (an older progress file)."""
    jobs = header.get("jobs")
    if not jobs or done >= jobs:
        return ""
    guess = estimate(header, header.get("events") or [], now)
    if guess is None:
        elapsed = now - float(header.get("start", now))
        return f", about {_clock(elapsed / done * (jobs - done))} left"
    seconds, untimed = guess
    if not untimed:
        return f", about {_clock(seconds)} left"
    kinds = "a kind" if untimed == 1 else "kinds"
    said = f"{count(untimed, 'job')} of {kinds} not timed yet"
    # those jobs at their kinds' times under another fault (sensor, car, road), though that changes a job's time:
    # a guess beside the bound, not in its place
    guessed = estimate(header, header.get("events") or [], now, guess=True)
    if guessed is not None and guessed[1] < untimed:
        keys = [k for k in header.get("swept") or [] if k in DATA_KEYS]
        where = f"another {keys[0]}" if len(keys) == 1 else "another fault, sensor, car or road"
        said += f"; {'at least' if guessed[1] else 'about'} {_clock(guessed[0])} at their times under {where}"
    return f", at least {_clock(seconds)} left ({said})"


def record_of(job_return: Any):
    """A job's return value: its record, or the exception of a job that raised (Hydra's JobReturn raises it)."""
    try:
        return getattr(job_return, "return_value", None)
    except Exception as exc:  # noqa: BLE001 - the line says how the job failed
        return exc


def job_line(header: dict, done: int, num, job_return: Any, seconds: float, now: float | None = None) -> str:
    """``[done/jobs] #num key=value ...: p1 .. %, p2 .. % (test, noise .., K=..) in .. s; sweep m:ss, about m:ss
    left``; a failed or interrupted job says so with its error. ``now``: the clock (time.time())."""
    now = time.time() if now is None else now
    jobs = header.get("jobs")
    which = _which(header, getattr(job_return, "overrides", None) or [])
    record = record_of(job_return)
    if isinstance(record, BaseException):
        outcome = f"failed ({type(record).__name__}: {record})"
    elif not isinstance(record, dict):
        outcome = "ended"
    elif record.get("status", "completed") != "completed":
        outcome = f"{record['status']} ({record.get('error') or 'no error recorded'})"
    else:
        outcome = headline(record.get("results")) or "completed"
    elapsed = now - float(header.get("start", now))
    count_ = f"{done}/{jobs}" if jobs else str(done)
    outcome = outcome.splitlines()[0][:160]
    left = left_text(header, done, now)
    return f"[{count_}] #{num} {which}: {outcome} in {seconds:.0f} s; sweep {_clock(elapsed)}{left}"


def _which(header: dict, given: list[str]) -> str:
    """A job's swept values, from its override strings."""
    overrides = {o.written_key: o.value for o in map(parse_override, given) if o.value is not None}
    swept = header.get("swept") or [k for k in ("objective", "seed") if k in overrides]  # as _swept_values names them
    return " ".join(f"{k}={_short(overrides[k])}" for k in swept if k in overrides)


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
