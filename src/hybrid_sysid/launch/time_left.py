"""A sweep's time left, from the starts, steps and ends its jobs wrote to the progress file
(hybrid_sysid.launch.progress).

Elapsed / done x remaining, the first estimate, said "about 32:36 left" when 2:16 remained. Four things made it
wrong, and each has its answer here:

- Start-up. A worker's first job pays the imports (seconds: benchmarks/README.md) and, with a cold cache, the
  dataset's simulation (minutes with data=paper), which no later job pays again; the sweep's clock also counts the
  launcher's own start. So a job's time is its own (its start to its end, in its worker), and a worker's
  first ("cold") job counts only its work as the record gives it (fit_seconds: training; a baseline's
  train_seconds: its fits), plus the overhead beyond the work that warm jobs show (scoring, writing).
- Parallel jobs. The first job to end is one of a wave that ends together; n at a time, the remaining jobs
  are laid on n workers, each next job on the first worker free, after what the running ones still need.
- Jobs of different kinds (baselines take seconds, networks minutes). A job's kind is its swept values but the
  seed; a kind's time is the mean of its ended jobs. In a re-run sweep, a kind whose jobs only ended at once
  (completed before) takes the work their records give.
- A kind none of whose jobs ended yet. Its running job reports its steps (core.steps): the seconds per step since
  its first twentieth (its first steps warm the libraries up) times its max_steps, plus the overhead, time it
  minutes before it ends. Else the kinds that differ from it only in values shown not to change a job's work
  (launch.kinds_alike: by the pairs of its own other values, else, for a fault, sensor, car or road, networks by
  networks and fits by fits; a kind's work the median of its jobs', in CPU seconds) time it, or, with nothing
  shown either way, a kind one fault, sensor, car or road away (a sweep over the fault alone said "at least 0:17"
  with about 50 minutes left), or one value away from a kind whose jobs train (the main job's objectives: "at
  least 0:00" with 2:12 left). A kind with none of these counts at the overhead alone: the estimate is then a
  lower bound, and the line says "at least" and how many jobs it did not time.
- A job resumed from its checkpoint (an interrupted sweep run again): its first step report is past step 0, and
  its time and recorded work are those of the steps left. It times nothing, as a re-run's completed job.
- A re-run's completed jobs (the header's "done_before", with their records' work) end at once. Counted as still
  to run, they made the first lines of a resumed sweep say "about 312:29 left" where 46:30 remained; they are
  done, and their records time their kinds until a job of the kind ends here.
"""

from __future__ import annotations

import heapq
import statistics

from hybrid_sysid.launch.kinds_alike import borrowed

OK = "completed"


def work_seconds(record) -> float | None:
    """The seconds of a record's own work: a network's fit (trainer.fit, validation included), else a baseline's
    fits (train_seconds of a run with no steps); None for anything else."""
    if not isinstance(record, dict) or record.get("status", OK) != OK:
        return None
    if record.get("fit_seconds") is not None:
        return float(record["fit_seconds"])
    if not record.get("steps") and record.get("train_seconds") is not None:
        return float(record["train_seconds"])
    return None


def work_cpu(record) -> float | None:
    """The CPU seconds of that work (fit_cpu_seconds), which other load on the machine hardly moves; None where the
    record has none (a plugin's baseline, a run recorded before the field)."""
    if not isinstance(record, dict) or record.get("status", OK) != OK or record.get("fit_cpu_seconds") is None:
        return None
    return float(record["fit_cpu_seconds"])


def _cycles(events: list[dict]) -> dict:
    """num -> the seconds from the previous end in the same worker to this job's end: its own time plus what the
    launcher spends between two jobs (a second or two: nothing beside a network's minutes, much beside a
    baseline's seconds)."""
    last, out = {}, {}
    for e in events:
        if "end" in e and e.get("pid") is not None and e.get("t") is not None:
            if e["pid"] in last and not e.get("cold"):
                out[e["end"]] = e["t"] - last[e["pid"]]
            last[e["pid"]] = e["t"]
    return out


def _timed(ends: dict, cycles: dict) -> tuple[dict, float]:
    """num -> (the seconds a job of its kind takes once the worker is warm, whether it ran warm); jobs that did no
    work of their own (a re-run sweep's completed job ends in less than its recorded work) and failed ones are
    left out, unless nothing else ended. And the overhead: a warm job's seconds beyond its work (median)."""
    warm = {}
    for num, e in ends.items():
        seconds, work = e.get("seconds"), e.get("work")
        if seconds is None or (work is not None and seconds < work):
            continue
        warm[num] = None if e.get("cold") else max(seconds, cycles.get(num, seconds))
    overheads = [warm[n] - ends[n]["work"] for n in warm if warm[n] is not None and ends[n].get("work") is not None]
    overhead = statistics.median(overheads) if overheads else 0.0
    out, failed = {}, {}
    for num, clean in warm.items():
        e = ends[num]
        if clean is None:  # a cold job: its work and the overhead warm jobs show, at most its own time
            clean = e["seconds"] if e.get("work") is None else min(e["seconds"], e["work"] + overhead)
        (out if e.get("ok", True) else failed)[num] = (clean, warm[num] is not None)
    return out or failed, overhead


def _mean(timed: list[tuple[float, bool]]) -> float:
    """The mean of warm times where there are any: a cold job's own work is slower too (the first fit of a process
    warms its libraries up: 13.3 s against 3.7 s for the next, on data=tiny)."""
    warm = [t for t, w in timed if w]
    return statistics.fmean(warm or [t for t, _ in timed])


def concurrency(events: list[dict]) -> int:
    """The most jobs seen running at once (a launcher that does not say how many it runs)."""
    running, most = set(), 1
    for e in events:
        if "start" in e:
            running.add(e["start"])
        elif "end" in e:
            running.discard(e["end"])
        most = max(most, len(running))
    return most


def rates_of(events: list[dict]) -> dict:
    """num -> (seconds per step, steps done, max_steps, the time of its last report) of a job with three reports
    or more: from its first twentieth on (its first steps start the data loading and warm the libraries up)."""
    reports: dict = {}
    for e in events:
        if "steps" in e and e.get("t") is not None and e.get("of"):
            r = reports.setdefault(e["steps"], [])
            if r and int(e["done"]) < r[-1][1]:  # a job of several fits (a chained experiment's): its latest
                r.clear()
            r.append((float(e["t"]), int(e["done"]), int(e["of"])))
    out = {}
    for num, r in reports.items():
        base, last = r[1 if len(r) >= 3 else -1], r[-1]
        if last[1] > base[1]:
            out[num] = ((last[0] - base[0]) / (last[1] - base[1]), last[1], last[2], last[0])
    return out


def resumed(events: list[dict]) -> set:
    """Jobs whose first step report is past step 0: resumed from a checkpoint, so their time and their record's
    work are a part of their kind's (a resumed network that ended in 166 s timed its kind at that, for 800 s)."""
    first: dict = {}
    for e in events:
        if "steps" in e and e.get("of"):
            first.setdefault(e["steps"], int(e["done"]))
    return {num for num, done in first.items() if done > 0}


def estimate(header: dict, events: list[dict], now: float, guess: bool = False) -> tuple[float, int] | None:
    """(seconds until the last job ends, how many of the jobs not ended are of a kind with no time: neither an
    ended job nor a running one's steps; the seconds are then a lower bound), or None when no job has a time (the
    caller falls back on elapsed / done x remaining). With ``guess``, kinds shown to cost differently under
    another fault, sensor, car or road take their mean there (``kinds_alike.borrowed``)."""
    jobs = header.get("jobs")
    kinds = header.get("kinds") or []
    starts, ends = {}, {}
    for e in events:
        if "start" in e:
            starts.setdefault(e["start"], e.get("t"))
        elif "end" in e:
            if e["end"] not in ends or e.get("seconds") is not None:  # the job's own entry, not the parent's
                ends[e["end"]] = e
    partial = resumed(events)
    whole = {num: e for num, e in ends.items() if num not in partial}  # the ended jobs whose times tell
    timed, overhead = _timed(whole, _cycles(events))

    def kind(num) -> str:
        return kinds[num] if isinstance(num, int) and 0 <= num < len(kinds) else ""

    by_kind: dict[str, list] = {}
    for num, t in timed.items():
        by_kind.setdefault(kind(num), []).append(t)
    means = {k: _mean(v) for k, v in by_kind.items()}
    works: dict[str, list] = {}
    cpus: dict[str, list] = {}
    for num, e in whole.items():
        if e.get("work") is not None and (num in timed or kind(num) not in means):
            works.setdefault(kind(num), []).append(float(e["work"]))
            if e.get("cpu") is not None:
                cpus.setdefault(kind(num), []).append(float(e["cpu"]))
    # a re-run sweep's completed jobs end at once, but their records say what a job of their kind took: that
    # times a kind none of whose jobs has run here yet (a resumed sweep of networks and baselines mixed)
    recorded: dict[str, list] = {}
    for num, e in whole.items():
        if num not in timed and e.get("ok", True) and e.get("work") is not None and kind(num) not in means:
            recorded.setdefault(kind(num), []).append(float(e["work"]))
    told = header.get("done_before") or {}
    before = {int(n): w for n, w in told.items() if str(n).isascii() and str(n).isdigit()}
    for num, work in before.items():  # those that have not said their end yet
        if num not in ends and work is not None and kind(num) not in means:
            recorded.setdefault(kind(num), []).append(float(work))
    means.update({k: statistics.fmean(v) for k, v in recorded.items()})
    running = [n for n in starts if n not in ends and n not in before]
    rates = {n: r for n, r in rates_of(events).items() if n in running and kind(n) not in means}
    stepped: dict[str, list] = {}
    for num, (rate, _, of, _) in rates.items():  # a kind timed by its running jobs' steps alone
        stepped.setdefault(kind(num), []).append(rate * of)
        works.setdefault(kind(num), []).append(rate * of)
    means.update({k: statistics.fmean(v) + overhead for k, v in stepped.items()})
    wanted = {kind(n) for n in range(int(jobs or 0)) if n not in ends and n not in before} - set(means)
    # the kinds whose jobs train: they report steps, or ended with a record of steps (a re-run's completed networks)
    trained = {e["steps"] for e in events if "steps" in e and e.get("of")}
    trained |= {num for num, e in ends.items() if e.get("trained")}
    networks = frozenset(map(kind, trained))
    # a kind's work by its median: one job slowed by other work on the machine does not make its kind differ
    median = {k: statistics.median(v) for k, v in works.items()}
    # a kind's CPU time where every job of it that tells has one (not a resumed sweep's older records mixed in)
    cpu = {k: statistics.median(v) for k, v in cpus.items() if len(v) == len(works[k])}
    means.update(borrowed(means, wanted, median, networks, cpu, guess))
    if not jobs or not (means or partial):  # resumed jobs alone: a lower bound, not their times per job
        return None
    floor = overhead  # what a job beyond its work takes: a kind with no time takes at least that
    untimed = 0

    def expected(num) -> float:
        nonlocal untimed
        if kind(num) in means:
            return means[kind(num)]
        untimed += 1
        return floor

    def still(num) -> float:
        """What running job ``num`` still needs: by its own steps where its kind has no ended job."""
        if num in rates:
            rate, done, of, at = rates[num]
            return max(rate * (of - done) - (now - at), 0.0) + overhead
        return max(expected(num) - (now - float(starts[num] or now)), 0.0)

    workers = header.get("at_once") or concurrency(events)
    slots = [still(n) for n in running]
    slots += [0.0] * max(int(workers) - len(slots), 0)
    heapq.heapify(slots)
    waiting = [n for n in range(int(jobs)) if n not in starts and n not in ends and n not in before]
    if not kinds:  # jobs numbered otherwise (a search's trials): the count alone
        waiting = list(range(max(int(jobs) - len(ends) - len(running), 0)))
    for num in waiting:
        heapq.heappush(slots, heapq.heappop(slots) + expected(num))
    return max(slots), untimed
