"""The time left a sweep's job lines print, against sweeps simulated on a clock of their own (no wall time): each
job's start and end as the launcher and the jobs would write them to the progress file (hybrid_sysid.launch.progress),
and the truth, the last job's end, known in advance."""

import json
from types import SimpleNamespace

import pytest

from hybrid_sysid.launch.progress import count_done, job_line, mark_start
from hybrid_sysid.launch.time_left import estimate

WITHIN = 0.30  # the estimate's promise once the first job has ended, relative to the truth


def close(seconds, truth, work) -> bool:
    """Within 30% of the truth, or, when only a few seconds remain, within the spread of the jobs' own times: with
    one job left running, its remaining time is that job's deviation from its kind's mean, which no estimate
    from the other jobs can know."""
    return abs(seconds - truth) <= max(WITHIN * truth, max(work) - min(work))


def simulate(kinds, work, workers, imports=7.0, data=0.0, gap=1.5, overhead=2.0, launch=5.0):
    """The progress events of a sweep: jobs dispatched in order to the first free worker, ``gap`` seconds of the
    launcher's before each job; a worker's first job imports (``imports`` s) and waits for the dataset, which
    the first jobs simulate once (``data`` s); each job then works ``work[i]`` s (what its record says) and
    scores and writes ``overhead`` s more. Returns (header, events in time order)."""
    free = [launch] * workers
    cold = [True] * workers
    data_ready = launch + gap + imports + data
    events = []
    for num, w in enumerate(work):
        i = min(range(workers), key=lambda j: (free[j], j))
        start = free[i] + gap
        ready = max(start + imports, data_ready) if cold[i] else start
        end = ready + w + overhead
        events.append({"start": num, "t": start, "pid": 100 + i})
        entry = {"t": end, "seconds": end - start, "cold": cold[i], "pid": 100 + i, "work": w, "ok": True}
        events.append({**entry, "end": num})
        free[i], cold[i] = end, False
    events.sort(key=lambda e: e["t"])
    return {"jobs": len(work), "start": 0.0, "at_once": workers, "kinds": kinds}, events


def checks(header, events):
    """(now, estimate, truth, untimed, elapsed / done x remaining) at every job's end but the last."""
    last = max(e["t"] for e in events)
    out, done = [], 0
    for n, e in enumerate(events):
        if "end" not in e or e["t"] == last:
            continue
        done += 1
        seconds, untimed = estimate(header, events[: n + 1], e["t"])
        old = e["t"] / done * (header["jobs"] - done)
        out.append((e["t"], seconds, last - e["t"], untimed, old))
    return out


def test_a_first_wave_that_simulated_the_dataset_does_not_inflate_the_estimate():
    """The issue's case: the first jobs paid the imports and minutes of simulation, later jobs a fraction of that.
    Elapsed / done x remaining said 32:36 where 2:16 remained; the estimate stays within 30% from the first end."""
    work = [25.0 + 3 * (i % 3) for i in range(12)]  # one kind, a spread like seeds'
    header, events = simulate(["objective=hybrid"] * 12, work, workers=2, data=240.0)
    for now, seconds, truth, untimed, _ in checks(header, events):
        assert untimed == 0
        assert close(seconds, truth, work), (now, seconds, truth)
    first = checks(header, events)[0]
    assert first[4] > 5 * first[2]  # the old formula, on the same events, was off by more than 5x


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_two_kinds_in_parallel_stay_within_30_percent_from_the_first_end(workers):
    """Two objectives of different cost, seeds inner (Hydra's order): the second kind is guessed at the first's
    mean until one of its jobs ends, and the line says how many jobs that guess covers."""
    kinds = ["objective=labelled"] * 4 + ["objective=hybrid"] * 4
    work = [60.0, 58.0, 63.0, 61.0, 72.0, 75.0, 70.0, 77.0]
    header, events = simulate(kinds, work, workers=workers, data=30.0)
    seen = checks(header, events)
    for now, seconds, truth, _, _ in seen:
        assert close(seconds, truth, work[4:]), (now, seconds, truth)
    assert seen[0][3] == 4  # at the first end: the four hybrid jobs are of a kind not timed yet
    assert seen[-1][3] == 0


def test_kinds_not_timed_yet_are_named_as_a_guess():
    """Baselines first (seconds), networks last (minutes): no estimate from the baselines alone can know the
    networks' time, so the lines say how many jobs are guessed; once a network ended, the estimate holds."""
    kinds = ["baseline=ls"] * 3 + ["objective=hybrid"] * 3
    work = [1.0, 1.2, 0.9, 300.0, 310.0, 290.0]
    header, events = simulate(kinds, work, workers=2)
    seen = checks(header, events)
    assert seen[0][3] == 3  # at the first end, the three networks are guessed at the baselines' mean
    assert seen[0][1] < 0.1 * seen[0][2]  # and that guess is far off, which is why the line says so
    for now, seconds, truth, untimed, _ in seen:
        if not untimed:
            assert close(seconds, truth, work[3:]), (now, seconds, truth)


def test_a_rerun_sweeps_skipped_jobs_and_failed_ones_time_nothing():
    """A re-run sweep's completed job returns its record at once (less time than its recorded work): it must not
    make the others look instant; nor does a job that failed at once."""
    header = {"jobs": 4, "start": 0.0, "at_once": 1, "kinds": [""] * 4}
    events = [
        {"start": 0, "t": 1.0, "pid": 1},
        {"end": 0, "t": 1.1, "seconds": 0.1, "cold": True, "pid": 1, "work": 100.0, "ok": True},  # skipped
        {"start": 1, "t": 1.2, "pid": 1},
        {"end": 1, "t": 1.3, "seconds": 0.1, "cold": False, "pid": 1, "work": None, "ok": False},  # failed at once
        {"start": 2, "t": 1.4, "pid": 1},
        {"end": 2, "t": 101.4, "seconds": 100.0, "cold": False, "pid": 1, "work": 98.0, "ok": True},
    ]
    seconds, untimed = estimate(header, events, 101.4)
    # one job left, timed by job 2 alone: from the end before it in its worker (the launcher's gap included)
    assert seconds == pytest.approx(101.4 - 1.3) and untimed == 0


def test_job_lines_from_the_progress_file(tmp_path):
    """The file as the workers write it: the line's estimate from its events, and plurals that fit the count."""
    path = tmp_path / ".progress"
    kinds = ["objective=a", "objective=a", "objective=b"]
    path.write_text(json.dumps({"jobs": 3, "swept": ["objective"], "start": 0.0, "at_once": 1, "kinds": kinds}) + "\n")
    mark_start(tmp_path, 0, 10.0, pid=7)
    header, done = count_done(tmp_path, 0, {"t": 70.0, "seconds": 60.0, "cold": False, "pid": 7, "work": 55.0})
    ret = SimpleNamespace(overrides=["objective=a"], return_value={"status": "completed"})
    line = job_line(header, done, 0, ret, 60.0, now=70.0)
    # two jobs left on one worker: one of kind a (60 s) and one of kind b, guessed at a's mean
    left = "about 2:00 left (1 job of a kind not timed yet)"
    assert line == f"[1/3] #0 objective=a: completed in 60 s; sweep 1:10, {left}"
    mark_start(tmp_path, 1, 70.0, pid=7)
    header, done = count_done(tmp_path, 1, {"t": 130.0, "seconds": 60.0, "cold": False, "pid": 7, "work": 55.0})
    assert job_line(header, done, 1, ret, 60.0, now=130.0).endswith("about 1:00 left (1 job of a kind not timed yet)")


def test_an_older_progress_file_falls_back_on_elapsed_per_job(tmp_path):
    path = tmp_path / ".progress"
    path.write_text(json.dumps({"jobs": 9, "start": 0.0}) + "\n3\n")  # a bare number per ended job
    header, done = count_done(tmp_path, 4)
    ret = SimpleNamespace(overrides=["seed=1"], return_value={"status": "completed"})
    assert done == 2 and job_line(header, done, 4, ret, 20.0, now=60.0).endswith("sweep 1:00, about 3:30 left")


def test_a_resumed_sweep_times_a_kind_by_its_completed_jobs_records():
    """A sweep of networks (300 s of work) and baselines (3 s), re-run after its first networks completed: they
    end at once, and the networks still waiting must be timed by those records, not by the baselines that ran
    here. The truth: the waiting jobs' times (their records' 300 s, the baselines' 5 s) laid on the two workers."""
    kinds = ["net"] * 6 + ["ls"] * 6
    header = {"jobs": 12, "start": 0.0, "at_once": 2, "kinds": kinds}
    events, t = [], 0.0
    for num in (0, 1):  # completed before: their records give 300 s of work, they end in 0.2 s
        events += [
            {"start": num, "t": t, "pid": 1},
            {"end": num, "t": t + 0.2, "seconds": 0.2, "cold": num == 0, "pid": 1, "work": 300.0, "ok": True},
        ]
        t += 0.2
    for num in (6, 7):  # two baselines run here, on two warm workers
        events += [{"start": num, "t": t, "pid": 1 + num % 2}]
    for num in (6, 7):
        events += [
            {"end": num, "t": t + 5.0, "seconds": 5.0, "cold": False, "pid": 1 + num % 2, "work": 3.0, "ok": True}
        ]
    now = t + 5.0
    seconds, untimed = estimate(header, events, now)
    # 4 networks and 4 baselines wait for 2 workers: 2 x 300 s + 2 x 5 s each
    truth = 2 * 300.0 + 2 * 5.0
    assert untimed == 0 and abs(seconds - truth) <= WITHIN * truth, (seconds, truth)
    # without the records' times the networks would count at the baselines' 5 s: far below the truth
    assert seconds > 10 * 2 * 5.0
