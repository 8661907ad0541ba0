"""The time left a sweep's job lines print, against sweeps simulated on a clock of their own (no wall time): each
job's start and end as the launcher and the jobs would write them to the progress file (hybrid_sysid.launch.progress),
and the truth, the last job's end, known in advance."""

import json
import re
from types import SimpleNamespace

import pytest
from omegaconf import OmegaConf

from hybrid_sysid.launch.progress import count_done, done_before, job_line, left_text, mark_start
from hybrid_sysid.launch.time_left import estimate

WITHIN = 0.30  # the estimate's promise once the first job has ended, relative to the truth


def close(seconds, truth, work) -> bool:
    """Within 30% of the truth, or, when only a few seconds remain, within the spread of the jobs' own times: with
    one job left running, its remaining time is that job's deviation from its kind's mean, which no estimate
    from the other jobs can know."""
    return abs(seconds - truth) <= max(WITHIN * truth, max(work) - min(work))


def simulate(kinds, work, workers, imports=7.0, data=0.0, gap=1.5, overhead=2.0, launch=5.0, steps=None, warmup=0.0):
    """The progress events of a sweep: jobs dispatched in order to the first free worker, ``gap`` seconds of the
    launcher's before each job; a worker's first job imports (``imports`` s) and waits for the dataset, which
    the first jobs simulate once (``data`` s); each job then works ``work[i]`` s (what its record says) and
    scores and writes ``overhead`` s more. A job of ``steps[i]`` > 0 optimiser steps reports them as the training
    does (core.steps: its first step, then each twentieth), its steps evenly spread over its work, but for a
    cold worker's first twentieth, ``warmup`` s slower (libraries warming up). Returns (header, events in time
    order)."""
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
        total = (steps or [0] * len(work))[num]
        slow = warmup if cold[i] else 0.0
        for done in range(0, total + 1, max(total // 20, 1)) if total else ():
            at = ready + slow * min(done / (total / 20), 1.0) + (w - slow) * done / total
            events.append({"steps": num, "t": at, "done": done, "of": total})
        entry = {"t": end, "seconds": end - start, "cold": cold[i], "pid": 100 + i, "work": w, "ok": True}
        events.append({**entry, "end": num})
        free[i], cold[i] = end, False
    events.sort(key=lambda e: e["t"])
    return {"jobs": len(work), "start": 0.0, "at_once": workers, "kinds": kinds}, events


def checks(header, events, at_steps=False):
    """(now, estimate, truth, untimed, elapsed / done x remaining) at every job's end but the last (and with
    ``at_steps``, at every step report after the first end as well, where a step line may print)."""
    last = max(e["t"] for e in events)
    out, done = [], 0
    for n, e in enumerate(events):
        if e["t"] == last or not ("end" in e or (at_steps and "steps" in e and done)):
            continue
        done += "end" in e
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
    """Two objectives of different cost, seeds inner (Hydra's order), 1000 steps each: until the second kind's
    steps time it, it takes the first's time (a network one value away: time_left.borrowed), 25% short of its
    own, and the estimate holds from the first end on, none of its jobs counted as not timed. The main job said
    "at least 0:00" where 2:12 remained before."""
    kinds = ["objective=labelled"] * 4 + ["objective=hybrid"] * 4
    work = [60.0, 58.0, 63.0, 61.0, 72.0, 75.0, 70.0, 77.0]
    header, events = simulate(kinds, work, workers=workers, data=30.0, steps=[1000] * 8)
    seen = checks(header, events, at_steps=True)
    for now, seconds, truth, untimed, _ in seen:
        if untimed:
            assert seconds <= truth, (now, seconds, truth)
        else:
            assert close(seconds, truth, work[4:]), (now, seconds, truth)
    first = next(c for c in seen if c[0] == min(e["t"] for e in events if "end" in e))
    assert first[3] == 0  # at the first end the four hybrid jobs, none a tenth of its steps done, are borrowed
    assert abs(first[1] - first[2]) <= WITHIN * first[2]


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


def test_a_job_resumed_from_its_checkpoint_times_nothing():
    """An interrupted sweep run again: job 0 resumes at step 1200 of 1500 and ends in 60 s (its record's work:
    the 50 s of those steps). The two jobs of its kind still to run take 300 s each, as job 1 shows once it
    ends; before that, a lower bound, never a kind timed at a resumed job's 60 s."""
    header = {"jobs": 3, "start": 0.0, "at_once": 1, "kinds": ["net"] * 3}
    events = [
        {"start": 0, "t": 0.0, "pid": 1},
        {"steps": 0, "t": 1.0, "done": 1200, "of": 1500},
        {"steps": 0, "t": 51.0, "done": 1500, "of": 1500},
        {"end": 0, "t": 60.0, "seconds": 60.0, "cold": True, "pid": 1, "work": 50.0, "ok": True},
        {"start": 1, "t": 61.0, "pid": 1},
    ]
    seconds, untimed = estimate(header, events, 61.0)
    assert untimed == 2  # jobs 1 and 2 not timed: "at least"
    events += [
        {"steps": 1, "t": 62.0, "done": 0, "of": 1500},
        {"end": 1, "t": 361.0, "seconds": 300.0, "cold": False, "pid": 1, "work": 295.0, "ok": True},
    ]
    seconds, untimed = estimate(header, events, 361.0)
    assert untimed == 0 and seconds == pytest.approx(300.0, rel=0.01)  # job 2, timed by job 1 alone


def test_job_lines_from_the_progress_file(tmp_path):
    """The file as the workers write it: the line's estimate from its events, and plurals that fit the count."""
    path = tmp_path / ".progress"
    kinds = ["objective=a", "objective=a", "objective=b"]
    path.write_text(json.dumps({"jobs": 3, "swept": ["objective"], "start": 0.0, "at_once": 1, "kinds": kinds}) + "\n")
    mark_start(tmp_path, 0, 10.0, pid=7)
    header, done = count_done(tmp_path, 0, {"t": 70.0, "seconds": 60.0, "cold": False, "pid": 7, "work": 55.0})
    ret = SimpleNamespace(overrides=["objective=a"], return_value={"status": "completed"})
    line = job_line(header, done, 0, ret, 60.0, now=70.0)
    # two jobs left on one worker: one of kind a (60 s) and one of kind b, not timed: at least the 5 s beyond its
    # work that job 0 took (a lower bound)
    left = "at least 1:05 left (1 job of a kind not timed yet)"
    assert line == f"[1/3] #0 objective=a: completed in 60 s; sweep 1:10, {left}"
    mark_start(tmp_path, 1, 70.0, pid=7)
    header, done = count_done(tmp_path, 1, {"t": 130.0, "seconds": 60.0, "cold": False, "pid": 7, "work": 55.0})
    assert job_line(header, done, 1, ret, 60.0, now=130.0).endswith(
        "at least 0:05 left (1 job of a kind not timed yet)"
    )


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


def test_a_resumed_sweep_does_not_wait_for_the_jobs_it_will_skip():
    """A sweep of ten 100-s jobs on two workers, run again after eight completed: those end at once, one after the
    other, and the two left take 100 s side by side. At every skipped end the estimate must say about 100 s (the
    truth), not the 4.5 x 100 s of nine jobs still to run."""
    header = {"jobs": 10, "start": 0.0, "at_once": 2, "kinds": [""] * 10}
    skipped = list(range(8))
    t = 0.0
    rerun = []
    for num in skipped:  # each returns its record in 0.05 s, on the first worker
        entry = {"t": t + 0.05, "seconds": 0.05, "cold": num == 0, "pid": 100, "work": 100.0, "ok": True}
        rerun += [{"start": num, "t": t, "pid": 100}, {**entry, "end": num}]
        t += 0.05
    for num in (8, 9):
        rerun += [{"start": num, "t": t, "pid": 100 + num % 2}]
    rerun += [
        {
            "end": num,
            "t": t + 100.0,
            "seconds": 100.0,
            "cold": num == 9,
            "pid": 100 + num % 2,
            "work": 100.0,
            "ok": True,
        }
        for num in (8, 9)
    ]
    header["done_before"] = {str(n): 100.0 for n in skipped}
    for n, e in enumerate(rerun[:16]):
        if "end" in e:
            seconds, untimed = estimate(header, rerun[: n + 1], e["t"])
            truth = rerun[-1]["t"] - e["t"]
            assert untimed == 0 and abs(seconds - truth) <= WITHIN * truth, (e, seconds, truth)
    # the same lines without the header's list: the jobs it skips count as jobs to run
    del header["done_before"]
    seconds, _ = estimate(header, rerun[:2], rerun[1]["t"])
    assert seconds > 3 * 100.0


def test_done_before_lists_the_completed_runs_of_a_sweep_directory(tmp_path):
    """What a re-run sweep's header says it will skip: the numbered directories whose record says completed, with
    their work; not a failed run, a truncated record, a directory of another name or a number beyond the sweep."""
    runs = {
        "0": {"status": "completed", "fit_seconds": 12.5},
        "1": {"status": "failed"},
        "3": {"status": "completed", "steps": 0, "train_seconds": 2.0},
        "7": {"status": "completed"},
        "notes": {"status": "completed"},
    }
    for name, record in runs.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "metrics.json").write_text(json.dumps(record))
    (tmp_path / "\u00b2").mkdir()  # a digit to str.isdigit, not to int
    (tmp_path / "2").mkdir()
    (tmp_path / "2" / "metrics.json").write_text('{"status": "compl')
    config = OmegaConf.create({"hydra": {"sweep": {"dir": str(tmp_path), "subdir": "${hydra.job.num}"}}})
    assert done_before(config, 5) == {"0": 12.5, "3": 2.0}
    config.hydra.sweep.subdir = "${hydra.job.override_dirname}"  # directories not named by number: none told
    assert done_before(config, 5) == {}


def test_networks_after_baselines_are_timed_by_their_steps_long_before_one_ends():
    """The anchored sweep's order on two workers: for each of two faults, a classical fit's three seeds (seconds),
    then two network kinds' three seeds each (minutes, steps and cost of their own). A kind is timed by its first
    network's steps from a tenth of them on; the second fault's kinds by the first's once a classical fit took as
    long under both. Until then the estimate is a lower bound and says so ("at least"); every other estimate is
    within 30% of the truth."""
    kinds, work, steps = [], [], []
    for fault in ("none", "drift"):
        for kind, seconds, n in (("ls", 1.0, 0), ("cnn", 300.0, 6000), ("anchored", 120.0, 1500)):
            for seed in range(3):
                kinds.append(f"fault={fault} estimator={kind}")
                work.append(seconds * (1 + 0.05 * seed) if n else seconds)  # seeds' spread
                steps.append(n)
    header, events = simulate(kinds, work, workers=2, steps=steps, warmup=20.0)
    seen = checks(header, events, at_steps=True)
    for now, seconds, truth, untimed, _ in seen:
        if untimed:  # nothing says what a kind costs yet: no more than the truth, as "at least" says
            assert seconds <= truth, (now, seconds, truth)
        else:
            assert close(seconds, truth, work[3:9]), (now, seconds, truth)
    # the second fault's classical fit ends as long as the first's: from then on every kind is timed
    drift = min(e["t"] for e in events if e.get("end") == 9)
    assert all(not c[3] for c in seen if c[0] >= drift) and any(c[0] >= drift for c in seen)
    # at a tenth of the first network's steps, its kind's three jobs are timed, which without steps they are not,
    # and so are the same kind's three under the second fault (one fault away, nothing showing the fault matters)
    tenth = next(e["t"] for e in events if e.get("steps") == 3 and e["done"] == 600)
    upto = [e for e in events if e["t"] <= tenth]
    blind = estimate(header, [e for e in upto if "steps" not in e], tenth)[1]
    assert estimate(header, upto, tenth)[1] == blind - 6


def test_a_network_alongside_baselines_is_timed_by_its_steps_at_every_later_end():
    """A network on one worker, thirty baselines ending one after the other on the other, a second network last:
    each baseline's end after the first network's tenth of steps estimates within 30% of the truth (the network's
    steps and the warm jobs' overhead); before, the line says "at least" and is no more than the truth."""
    kinds = ["estimator=cnn"] + ["estimator=ls"] * 30 + ["estimator=cnn"]
    work = [200.0] + [4.0] * 30 + [210.0]
    steps = [3000] + [0] * 30 + [3000]
    header, events = simulate(kinds, work, workers=2, steps=steps, warmup=10.0)
    seen = checks(header, events)
    tenth = next(e["t"] for e in events if e.get("steps") == 0 and e["done"] == 300)
    later = [c for c in seen if c[0] >= tenth]
    assert later and all(not c[3] for c in later)
    for now, seconds, truth, _, _ in later:
        assert close(seconds, truth, [200.0, 210.0]), (now, seconds, truth)
    before = [c for c in seen if c[0] < tenth]
    assert before and all(c[3] and c[1] <= c[2] for c in before)


def test_step_reports_at_the_first_step_and_each_twentieth(monkeypatch):
    """training.callbacks.StepReports, on a trainer's step counter: a report at the fit's start and at each
    multiple of max_steps / 20 (core.steps.PARTS), none on a rank above 0 or when nobody listens."""
    from hybrid_sysid.core import steps
    from hybrid_sysid.training.callbacks import StepReports

    def fit(max_steps, start=0, zero=True):
        heard = []
        steps.listen(lambda done, total: heard.append((done, total)))
        try:
            trainer = SimpleNamespace(global_step=start, max_steps=max_steps, is_global_zero=zero)
            cb = StepReports()
            cb.on_train_start(trainer, None)
            while trainer.global_step < max_steps:
                trainer.global_step += 1
                cb.on_train_batch_end(trainer, None, None, None, 0)
        finally:
            steps.listen(None)
        return heard

    assert fit(300) == [(d, 300) for d in range(0, 301, 15)]
    assert fit(10) == [(d, 10) for d in range(0, 11)]  # fewer steps than parts: every step
    assert fit(300, start=100) == [(100, 300)] + [(d, 300) for d in range(105, 301, 15)]  # a resumed fit
    assert fit(300, zero=False) == []


def test_a_step_line_once_for_a_kind_not_timed_yet(tmp_path):
    """The worker's line from a job's steps (progress.mark_steps): once per kind with no ended job, after a first
    end, only when the job still needs more than STEP_LINE_AFTER; its estimate is the steps' (no "at least")."""
    from hybrid_sysid.launch.progress import STEP_LINE_AFTER, mark_steps

    kinds = ["estimator=ls", "estimator=cnn", "estimator=cnn"]
    header = {"jobs": 3, "swept": ["estimator"], "start": 0.0, "at_once": 2, "kinds": kinds}
    (tmp_path / ".progress").write_text(json.dumps(header) + "\n")
    mark_start(tmp_path, 0, 1.0, pid=1)
    mark_start(tmp_path, 1, 1.0, pid=2)
    given = ["estimator=cnn"]
    assert mark_steps(tmp_path, 1, given, 0, 300, 1.0, 10.0) is None  # no job ended: no line guessed the kind
    count_done(tmp_path, 0, {"t": 11.0, "seconds": 10.0, "cold": True, "pid": 1, "work": 1.0, "ok": True})
    mark_start(tmp_path, 2, 11.0, pid=1)
    assert mark_steps(tmp_path, 1, given, 15, 300, 1.0, 20.0) is None  # its first twentieth alone: no rate yet
    line = mark_steps(tmp_path, 1, given, 30, 300, 1.0, 35.0)  # 1 s a step from the 15th on
    # job 1 needs 270 s more; job 2, on the other worker since 11 s, 300 steps at 1 s (no warm job: no overhead)
    # less the 24 s it ran: the last ends in max(270, 276) s
    assert line == "[1/3 ended] #1 estimator=cnn: step 30 of 300 in 34 s; sweep 0:35, about 4:36 left", line
    assert mark_steps(tmp_path, 2, given, 30, 300, 11.0, 40.0) is None  # said once for the kind
    assert 270 > STEP_LINE_AFTER


def test_no_step_line_for_a_kind_timed_by_kinds_as_long(tmp_path):
    """A network under a second fault, once a baseline took as long under both faults and the network ended under
    the first: its kind is timed already (time_left.borrowed), the last line said "about", so its steps print
    nothing; the estimate times it at the first fault's network."""
    from hybrid_sysid.launch.progress import mark_steps

    kinds = ["fault=a est=ls", "fault=b est=ls", "fault=a est=cnn", "fault=b est=cnn"]
    header = {"jobs": 4, "swept": ["fault", "est"], "start": 0.0, "at_once": 1, "kinds": kinds}
    (tmp_path / ".progress").write_text(json.dumps(header) + "\n")
    t = 0.0
    for num, seconds in enumerate([10.0, 10.0, 100.0]):  # one warm worker: each takes 2 s beyond its work
        mark_start(tmp_path, num, t, pid=1)
        t += seconds
        count_done(tmp_path, num, {"t": t, "seconds": seconds, "cold": False, "pid": 1, "work": seconds - 2.0})
    mark_start(tmp_path, 3, t, pid=1)
    for done, at in ((0, 1.0), (15, 16.0), (30, 31.0)):  # 1 s a step: 300 s, where the first fault's took 100 s
        assert mark_steps(tmp_path, 3, ["fault=b", "est=cnn"], done, 300, t, t + at) is None
    header, *events = map(json.loads, (tmp_path / ".progress").read_text().splitlines())
    seconds, untimed = estimate(header, [e for e in events if "steps" not in e], t + 31.0)
    assert untimed == 0 and seconds == pytest.approx(100.0 - 31.0)
    # with its steps the job's own rate wins: 270 steps at 1 s and the 2 s beyond the work
    assert estimate(header, events, t + 31.0) == (pytest.approx(270.0 + 2.0), 0)


def test_a_jobs_step_rate_leaves_its_first_twentieth_and_earlier_fits_out():
    """rates_of: seconds per step from a job's second report on (its first steps load data and warm libraries
    up); a job of several fits (a chained experiment's) is timed by its latest fit alone."""
    from hybrid_sysid.launch.time_left import rates_of

    def reports(*points):
        return [{"steps": 4, "t": t, "done": d, "of": of} for t, d, of in points]

    first = reports((0.0, 0, 100), (30.0, 5, 100))  # two reports: the first twentieth alone, no rate
    assert rates_of(first) == {}
    later = first + reports((40.0, 10, 100), (50.0, 15, 100))  # 2 s a step after the slow start
    assert rates_of(later) == {4: (2.0, 15, 100, 50.0)}
    second_fit = later + reports((60.0, 0, 40), (61.0, 2, 40), (64.0, 4, 40))  # 1.5 s a step
    assert rates_of(second_fit) == {4: (1.5, 4, 40, 64.0)}


def test_kinds_compared_by_their_work_not_a_new_faults_dataset_load():
    """The first jobs under a new fault load its dataset (10 s here) besides their 1 s of fits: their fits, not
    their time, show the fault does not change a job's time, so the network under it is timed by the first
    fault's network at once; a fault whose fits took three times as long times nothing."""
    kinds = ["fault=a est=ls"] * 2 + ["fault=a est=cnn"] * 2 + ["fault=b est=ls"] * 2 + ["fault=b est=cnn"] * 2
    header = {"jobs": 8, "start": 0.0, "at_once": 1, "kinds": kinds}

    def sweep(fits_b):
        events, t = [], 0.0
        for num, (seconds, work) in enumerate([(3, 1), (3, 1), (100, 98), (100, 98), (12 + fits_b, fits_b)]):
            events.append({"start": num, "t": t, "pid": 1})
            t += seconds
            events.append({"end": num, "t": t, "seconds": seconds, "cold": False, "pid": 1, "work": work, "ok": True})
        return estimate(header, events, t)

    seconds, untimed = sweep(fits_b=1.0)
    # three jobs left on one worker: fault b's second ls at its first's 13 s, two networks at fault a's 100 s
    assert untimed == 0 and seconds == pytest.approx(13.0 + 2 * 100.0)
    assert sweep(fits_b=3.0)[1] == 2  # 3 s of fits against 1 s: fault b's networks are not timed


def test_a_sweep_over_the_fault_alone_is_timed_by_its_first_fault():
    """One estimator under five faults, three seeds each, one at a time (the anchored_bayes sweep): no two faults
    have ended when the first fault's jobs end, and the line said "at least 0:17" with about 50 minutes left. The
    other faults are now taken to cost as much: within 30% from the first end, none counted as not timed."""
    faults = ("clean", "gain", "skewed", "lowpass", "hardening")
    kinds = [f"fault={f}" for f in faults for _ in range(3)]
    work = [250.0 + 10 * (i % 3) + 15 * (i // 3) for i in range(15)]  # a fault's own cost, within 25% of another's
    header, events = simulate(kinds, work, workers=1)
    seen = checks(header, events)
    for now, seconds, truth, untimed, _ in seen:
        assert untimed == 0
        assert close(seconds, truth, work), (now, seconds, truth)


def test_a_sweep_over_the_estimator_alone_still_says_what_it_did_not_time():
    """Where the one swept key chooses what is computed (a baseline of seconds, a network of minutes), the first
    kind's time says nothing of the second's: the estimate stays a lower bound until the second is timed."""
    kinds = ["estimator=ls"] * 3 + ["estimator=cnn"] * 3
    header, events = simulate(kinds, [1.0, 1.1, 0.9, 300.0, 310.0, 290.0], workers=1)
    first = checks(header, events)[0]
    assert first[3] == 3 and first[1] < first[2]


def test_two_baselines_as_fast_do_not_time_a_network_of_the_same_key():
    """experiment=anchored_clean's order: two classical fits as fast (ls, eiv), then networks under the same key. The
    first two showed the estimator not to change a baseline's time, which says nothing of a network's: the line
    said "about 0:08" with 13:04 left. The networks stay not timed ("at least", no more than the truth) until
    their steps time them."""
    kinds = ["estimator=ls"] * 3 + ["estimator=eiv"] * 3 + ["estimator=anchored"] * 3
    work = [1.0, 1.1, 0.9, 1.0, 1.2, 1.1, 220.0, 230.0, 225.0]
    header, events = simulate(kinds, work, workers=2, steps=[0] * 6 + [1500] * 3)
    eiv_ended = max(e["t"] for e in events if e.get("end") in (3, 4, 5))
    upto = [e for e in events if e["t"] <= eiv_ended and "steps" not in e]
    seconds, untimed = estimate(header, upto, eiv_ended)
    truth = max(e["t"] for e in events) - eiv_ended
    assert untimed == 3 and seconds <= truth, (seconds, truth, untimed)


def test_a_faults_slower_fixed_fit_does_not_untime_the_networks_under_the_next_fault():
    """The anchored sweep's case: under the second fault the classical fit takes three times as long (its fixed fit
    fits the fault too), which showed the fault to matter for every kind, and the third fault's networks counted
    as not timed ("at least 12:01" with about 4 h 30 min left). A kind is judged by the pairs of its own estimator
    (else networks by networks): two faults' networks trained as long, and so did their plain fits, so the third
    fault's are timed by them; its fixed fit waits for its own."""
    kinds, work, steps = [], [], []
    for fault, fix in (("clean", 1.0), ("gain", 3.0), ("skewed", 1.0)):
        for estimator, seconds, n in (("ls", 1.0, 0), ("ls_fix", fix, 0), ("cnn", 100.0, 1000)):
            for seed in range(2):
                kinds.append(f"fault={fault} estimator={estimator}")
                work.append(seconds * (1 + 0.05 * seed))
                steps.append(n)
    header, events = simulate(kinds, work, workers=1, steps=steps)
    fits_ended = max(e["t"] for e in events if e.get("end") in (14, 15))
    upto = [e for e in events if e["t"] <= fits_ended]
    seconds, untimed = estimate(header, upto, fits_ended)
    truth = max(e["t"] for e in events) - fits_ended
    assert untimed == 0 and close(seconds, truth, work[4:6]), (seconds, truth, untimed)
    # before, the third fault's fixed fits are not timed (the fault changed a fixed fit's time), and its plain fits
    # (two faults alike) and networks are
    fits_started = min(e["t"] for e in events if e.get("start") == 12)
    upto = [e for e in events if e["t"] <= fits_started]
    assert estimate(header, upto, fits_started)[1] == 2


def test_a_rerun_sweeps_completed_networks_time_the_next_faults_networks():
    """A re-run sweep: the first fault's fit and network completed before and end at once, the network's record
    saying it trained (no step reports in this run). The second fault's fit runs here and takes three times its
    record, so the fault changes a fit's time; nothing says it changes a network's, which the completed network
    now times (it counted as not timed, as if it were a fit)."""
    kinds = ["fault=clean estimator=ls_fix", "fault=clean estimator=cnn"]
    kinds += ["fault=gain estimator=ls_fix", "fault=gain estimator=cnn"]
    header = {"jobs": 4, "start": 0.0, "at_once": 1, "kinds": kinds}
    done = {"seconds": 0.1, "cold": False, "pid": 1, "ok": True}
    events = [
        {"start": 0, "t": 0.0, "pid": 1},
        {**done, "end": 0, "t": 0.1, "work": 1.0, "trained": False},
        {"start": 1, "t": 0.1, "pid": 1},
        {**done, "end": 1, "t": 0.2, "work": 100.0, "trained": True},
        {"start": 2, "t": 0.2, "pid": 1},
        {"end": 2, "t": 5.2, "seconds": 5.0, "cold": False, "pid": 1, "work": 3.0, "ok": True, "trained": False},
    ]
    seconds, untimed = estimate(header, events, 5.2)
    assert untimed == 0 and seconds == pytest.approx(100.0, rel=0.1), (seconds, untimed)
    unflagged = [{k: v for k, v in e.items() if k != "trained"} for e in events]
    assert estimate(header, unflagged, 5.2)[1] == 1  # the old progress lines: the network was taken for a fit


def test_one_job_slowed_by_other_work_does_not_make_its_fault_differ():
    """A network under the second fault trained three times as long once, while other work ran on the machine (the
    anchored sweep's gain fault: 920 s against 139 and 169 s): its kind is judged by the median of its jobs, so the
    third fault's networks are still timed by the first two faults'."""
    kinds = [f"fault={f} estimator=cnn" for f in ("clean", "gain", "skewed") for _ in range(3)]
    header = {"jobs": 9, "start": 0.0, "at_once": 1, "kinds": kinds}
    events, t = [], 0.0
    for num, work in enumerate([150.0, 160.0, 155.0, 140.0, 920.0, 170.0]):
        events.append({"start": num, "t": t, "pid": 1})
        t += work + 2.0
        events.append({"end": num, "t": t, "seconds": work + 2.0, "cold": False, "pid": 1, "work": work, "ok": True})
    seconds, untimed = estimate(header, events, t)
    assert untimed == 0 and seconds > 3 * 140.0, (seconds, untimed)


def test_kinds_compared_by_their_cpu_time_where_load_moved_their_wall_time():
    """Skewed's networks trained 183 s beside idle cores against clean's 352 s beside benchmarks: their wall times
    marked the fault as changing a network's time, and the third fault's counted as not timed. Their CPU times
    (the records' fit_cpu_seconds) were alike, so they now time it; CPU times as far apart as the wall times still
    time nothing."""
    kinds = [f"fault={f} estimator=cnn" for f in ("clean", "skewed", "lowpass") for _ in range(2)]
    header = {"jobs": 6, "start": 0.0, "at_once": 1, "kinds": kinds}

    def sweep(cpus):
        events, t = [], 0.0
        for num, (work, cpu) in enumerate(zip([352.0, 350.0, 183.0, 180.0], cpus)):
            events.append({"start": num, "t": t, "pid": 1})
            t += work + 2.0
            entry = {"t": t, "seconds": work + 2.0, "cold": False, "pid": 1, "work": work, "cpu": cpu, "ok": True}
            events.append({**entry, "end": num})
        return estimate(header, events, t)

    seconds, untimed = sweep([175.0, 174.0, 170.0, 172.0])
    assert untimed == 0 and seconds > 2 * 180.0, (seconds, untimed)
    assert sweep([352.0, 350.0, 183.0, 180.0])[1] == 2  # the CPU, as the wall, says the fault matters
    assert sweep([None] * 4)[1] == 2  # records without it: their wall times, as before


def test_a_fault_shown_to_change_the_networks_time_is_guessed_beside_the_bound():
    """The anchored sweep after three faults: the skew fix doubled the anchored networks' time under one fault, so
    the next faults' networks are not timed, and the line said "at least 0:04" with about 3 h 30 min left. The
    bound stays, and beside it the same kinds at their mean under the other faults: within 30% of the truth where
    the next fault costs as the others do on average, a lower bound otherwise."""
    per_fault = {"clean": 100.0, "skewed": 200.0, "lowpass": 190.0, "hardening": 110.0}
    kinds, work = [], []
    for fault, seconds in per_fault.items():
        for seed in range(2):
            kinds.append(f"fault={fault} estimator=cnn")
            work.append(seconds * (1 + 0.02 * seed))
    header, events = simulate(kinds, work, workers=1)
    header["swept"] = ["fault", "estimator", "seed"]
    ended = max(e["t"] for e in events if e.get("end") == 3)  # two faults done
    upto = [e for e in events if e["t"] <= ended]
    truth = max(e["t"] for e in events) - ended
    bound, untimed = estimate(header, upto, ended)
    assert untimed == 4 and bound < truth
    seconds, still = estimate(header, upto, ended, guess=True)
    assert still == 0 and close(seconds, truth, work), (seconds, truth)
    # the line says both: the bound and the guess, naming the key that was guessed across
    line = left_text({**header, "events": upto}, 4, ended)
    said = re.search(
        r"at least ([\d:]+) left \(4 jobs of kinds not timed yet; about ([\d:]+) at their times under "
        r"another fault\)$",
        line,
    )
    assert said, line
    as_seconds = [sum(int(x) * 60**i for i, x in enumerate(reversed(c.split(":")))) for c in said.groups()]
    assert as_seconds == [pytest.approx(bound, abs=1), pytest.approx(seconds, abs=1)], line
