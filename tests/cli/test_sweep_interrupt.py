"""A sweep's signals and its end, beside tests/cli/test_faults.py's signalled sweeps: a parallel sweep signalled
while its workers start up, a job not yet started when the sweep was interrupted, a worker between its jobs, and a
summary that cannot be written. One real process where the process is what is tested (its workers, its exit
status and output); the rest in this process, on run_job and the sweep's callback."""

import json
import os
import signal
import time
from pathlib import Path

import pandas as pd
import pytest
from omegaconf import OmegaConf

from helpers import app_process
from helpers.started_early import started_early

TINY = ["data=tiny", "trainer=debug", "trainer.max_steps=10", "trainer.eval_every_n_steps=5"]


def starting_workers(pid: int) -> list[int]:
    """The sweep's loky workers that have started but have no SIGTERM handler yet (still importing, before their
    first job)."""
    from hybrid_sysid.launch.process import catches_sigterm

    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            ppid = stat.read_text().rsplit(")", 1)[1].split()[1]
            cmdline = (stat.parent / "cmdline").read_bytes()
        except (OSError, IndexError):
            continue
        if ppid == str(pid) and b"loky" in cmdline and b"resource_tracker" not in cmdline:
            if not catches_sigterm(int(stat.parent.name)):
                found.append(int(stat.parent.name))
    return found


@started_early
def sweep_terminated_as_workers_start(tmp, env, tiny_cache):
    """A real joblib sweep, SIGTERM to its parent as soon as a worker exists that has not reached its first job:
    (whether a starting worker was seen, exit status, its output, the sweep directory)."""
    sw = tmp / "sw"
    args = ["-m", "launcher=joblib", "seed=0,1,2", *TINY, "trainer.progress_bar=false", f"hydra.sweep.dir={sw}"]
    proc = app_process.launch(tmp, *args, cache=tiny_cache, env=env)
    deadline, seen = time.time() + 300, False
    while proc.poll() is None and time.time() < deadline and not seen:
        seen = bool(starting_workers(proc.pid))
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=600)
    return seen, proc.returncode, out, sw


def test_sigterm_while_a_parallel_sweeps_workers_start_is_143_without_a_traceback(
    sweep_terminated_as_workers_start,
):
    seen, code, out, sw = sweep_terminated_as_workers_start
    assert seen, "the sweep ended before its workers started"
    assert code == 128 + signal.SIGTERM, out[-3000:]
    assert "Traceback" not in out, out[-3000:]
    statuses = {p.parent.name: json.loads(p.read_text())["status"] for p in sw.glob("*/metrics.json")}
    assert statuses == {"0": "interrupted", "1": "interrupted", "2": "interrupted"}  # no job dropped
    summary = pd.read_csv(sw / "summary.csv", dtype={"run": str})
    assert set(summary.run) == {"0", "1", "2"} and set(summary.status) == {"interrupted"}


@pytest.fixture
def worker(tmp_path, monkeypatch):
    """This process as a sweep's worker between jobs: its signal handlers and the sweep's state put back after.
    It has no workers of its own: its children are other tests' processes started early, which a signal passed on
    by the sweep's handler (stop_sweep) would end."""
    from hybrid_sysid.launch import process
    from hybrid_sysid.launch.process import PROCESS, SIGNALS

    monkeypatch.setattr(process, "children", lambda: [])
    handlers = {s: signal.getsignal(s) for s in SIGNALS}
    PROCESS.reset()
    sw = tmp_path / "sw"
    sw.mkdir()
    yield sw
    for s, handler in handlers.items():
        signal.signal(s, handler)
    PROCESS.reset()


def record(run_dir):
    return json.loads((run_dir / "metrics.json").read_text())


def test_a_job_not_started_when_the_sweep_was_interrupted_records_it_without_running(worker):
    from hybrid_sysid.launch.job import run_job
    from hybrid_sysid.runs.layout import STOP_MARKER

    sw = worker
    (sw / STOP_MARKER).touch()  # another of the sweep's processes took the signal
    ran = []
    result = run_job(lambda: ran.append(1), sw / "0", ["seed=0"], 0, multirun=True, sweep_dir=sw)
    assert ran == [] and result["status"] == "interrupted"
    assert record(sw / "0")["status"] == "interrupted" and record(sw / "0")["error"].startswith("not started")


def test_a_parallel_worker_keeps_the_sweeps_signal_handling_between_its_jobs(worker):
    """A worker of a parallel sweep (its parent's sweep directory unknown to it) finishes a job, takes SIGTERM
    before the next: it lives on, and the next job records its interruption without running."""
    from hybrid_sysid.launch.job import run_job

    sw, ran = worker, []
    first = run_job(lambda: {"status": "completed"}, sw / "0", ["seed=0"], 0, multirun=True, sweep_dir=None)
    assert first == {"status": "completed"}
    os.kill(os.getpid(), signal.SIGTERM)  # between the jobs: the default handler would end this process here
    second = run_job(lambda: ran.append(1), sw / "1", ["seed=1"], 1, multirun=True, sweep_dir=None)
    assert ran == [] and second["status"] == "interrupted"
    assert record(sw / "1")["error"] == "not started: interrupted by SIGTERM"


def test_a_summary_that_cannot_be_written_ends_the_sweep_nonzero(tmp_path, monkeypatch):
    """The sweep's end raises SystemExit, which Hydra's callback runner passes on (it turns an Exception of a
    callback into a warning and exit status 0)."""
    import hybrid_sysid.report.summary as summary
    from hybrid_sysid.launch.sweep import SweepSummary

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(summary, "write_summary", full_disk)
    config = OmegaConf.create({"hydra": {"sweep": {"dir": str(tmp_path)}}})
    with pytest.raises(SystemExit) as ended:
        SweepSummary().on_multirun_end(config)
    assert not isinstance(ended.value, Exception)
    assert ended.value.code not in (0, None)  # a message: the interpreter prints it and exits with status 1
    assert "no summary written" in str(ended.value.code) and "No space left" in str(ended.value.code)
