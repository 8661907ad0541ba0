"""A parallel sweep's workers end when its parent is killed (SIGKILL: it can pass nothing on), rather than run the
remaining jobs into the dead sweep and idle for good (hybrid_sysid.launch.orphans)."""

import contextlib
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hybrid_sysid.launch.orphans import exit_with_parent

from helpers.app_process import user_env

SWEEP = [
    "-m",
    "launcher=joblib",
    "hydra.launcher.n_jobs=2",
    "seed=0,1,2,3",
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=400",
    "trainer.eval_every_n_steps=100",
    "trainer.progress_bar=false",
]
BOUND = 60  # seconds for every worker to be gone after the parent's death


def stat(pid: int) -> tuple[int, str, int] | None:
    """(parent pid, state, start time) of a process, from /proc; None once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return int(fields[1]), fields[0], int(fields[19])


def descendants(root: int) -> dict[int, int]:
    """Every process below ``root`` (children, their children...) -> its start time (which tells a reused pid)."""
    table = {}
    for path in Path("/proc").glob("[0-9]*"):
        info = stat(int(path.name))
        if info is not None:
            table[int(path.name)] = info
    found, todo = {}, [root]
    while todo:
        parent = todo.pop()
        for pid, (ppid, _, start) in table.items():
            if ppid == parent and pid not in found:
                found[pid] = start
                todo.append(pid)
    return found


def alive(pid: int, start: int) -> bool:
    """Running, and the same process: a zombie (exited, not yet reaped) or a gone pid counts as dead."""
    info = stat(pid)
    return info is not None and info[2] == start and info[1] not in ("Z", "X")


def command(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")[:150]
    except OSError:
        return "?"


def watchers() -> int:
    return sum(t.name == "exit-with-parent" for t in threading.enumerate())


def started_twice() -> tuple[bool, bool, int]:
    return exit_with_parent(), exit_with_parent(), watchers()


def test_only_a_started_worker_watches_its_parent_and_only_once():
    # this process, like a single run or a basic launcher's sweep, was not started by multiprocessing or loky
    assert exit_with_parent() is False and watchers() == 0
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        assert pool.apply(started_twice) == (True, False, 1)


WATCHED = """
import signal, sys, threading, time
from hybrid_sysid.launch import orphans
signal.signal(signal.SIGTERM, lambda *_: print("SIGTERM", flush=True))  # as the job's handler: a request
job, grace = float(sys.argv[1]), float(sys.argv[2])
with orphans.job_in_progress():
    # the watcher of a worker whose parent is already gone (no process has pid -1)
    threading.Thread(target=orphans._watch, args=(-1, 0.01, grace), daemon=True).start()
    time.sleep(job)  # the job, until its record is written
    print("recorded", flush=True)
time.sleep(60)
print("idle through the grace", flush=True)
"""


@pytest.mark.parametrize(
    "job, grace, said",
    [(1.0, 600.0, ["SIGTERM", "recorded"]), (600.0, 1.0, ["SIGTERM"])],
    ids=["exits-once-the-job-recorded", "the-grace-bounds-a-job-that-never-records"],
)
def test_an_orphaned_worker_exits_once_its_job_has_recorded(job, grace, said):
    # a process of its own: the watcher ends the process it runs in
    done = subprocess.run(
        [sys.executable, "-c", WATCHED, str(job), str(grace)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 128 + signal.SIGTERM, done.stderr[-2000:]
    assert done.stdout.split() == said  # waited for the record, not for the grace; or not past the grace


@pytest.mark.integration
@pytest.mark.faults
def test_a_killed_sweeps_workers_record_the_interruption_and_exit(tmp_path, tiny_cache, no_process_started_early):
    # real processes: a sweep's parent killed, its workers left orphaned. Alone on the cores: a worker has at most
    # GRACE_SECONDS (orphans.py) from its parent's death to record its job, and the test bounds how soon all are
    # gone
    sw = tmp_path / "sw"
    env = user_env(cache=tiny_cache)  # data=tiny, simulated once for the test run
    # a file, not a pipe: the workers outlive the parent and would block on a pipe nobody reads
    with open(tmp_path / "out.txt", "w") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "hybrid_sysid", *SWEEP, f"hydra.sweep.dir={sw}"],
            cwd=tmp_path,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    procs: dict[int, int] = {}
    try:
        deadline = time.time() + 600
        # both workers have started a job (each then watches the parent)
        while len(list(sw.glob("*/.hydra/config.yaml"))) < 2 and proc.poll() is None and time.time() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "the sweep ended before its parent could be killed"
        started = sorted(p.parents[1] for p in sw.glob("*/.hydra/config.yaml"))
        procs = descendants(proc.pid)  # the loky workers and loky's resource tracker
        assert len(procs) >= 2, [command(p) for p in procs]
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
        killed = time.time()
        while any(alive(p, s) for p, s in procs.items()) and time.time() < killed + BOUND:
            time.sleep(0.1)
        left = [f"{p}: {command(p)}" for p, s in procs.items() if alive(p, s)]
        print(f"{len(procs)} processes below the parent gone {time.time() - killed:.1f} s after its SIGKILL")
        assert not left, f"still running {BOUND} s after the parent's SIGKILL: {left}"
        # the jobs that were running recorded how they ended
        statuses = {run.name: json.loads((run / "metrics.json").read_text())["status"] for run in started}
        assert set(statuses.values()) <= {"completed", "interrupted"}, statuses
        assert "interrupted" in statuses.values(), statuses
    finally:
        for pid, start in procs.items():  # nothing outlives the test, whatever failed
            if alive(pid, start):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
