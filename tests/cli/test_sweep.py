"""Multirun sweeps in a subprocess, as a user launches them: summary, failures, joblib, the report command."""

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from helpers import app_process
from helpers.started_early import started_early

pytestmark = pytest.mark.integration  # subprocess runs of the app: minutes, still in the default suite

TINY = [
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=10",
    "trainer.eval_every_n_steps=5",
    "trainer.progress_bar=false",
]


def run_app(tmp_path, *args, cache=None, env=None):
    """The app in a new process, as a user starts a sweep; ``cache``: the shared tiny_cache (the jobs then read
    data=tiny instead of simulating it), else an empty one of the test's own; ``env``: else this process's."""
    return app_process.run_app(tmp_path, *args, cache=cache or tmp_path / "cache", env=env)


def test_summary_csv_equals_the_jobs_records(tiny_sweep):
    proc, sw = tiny_sweep  # objective=labelled,hybrid seed=0,1 (conftest.py)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_csv(sw / "summary.csv", dtype={"run": str})
    jobs = sorted(p for p in sw.iterdir() if (p / "metrics.json").exists())
    assert len(jobs) == 4
    for job in jobs:
        record = json.loads((job / "metrics.json").read_text())
        assert record["status"] == "completed"
        for r in record["results"]:
            row = summary[
                (summary.run == job.name)
                & (summary.split == r["split"])
                & (summary.noise_std == r["noise_std"])
                & (summary.parameter == r["parameter"])
            ]
            assert len(row) == 1
            assert row.mean_rel_dev.item() == r["mean_rel_dev"] and row.std_rel_dev.item() == r["std_rel_dev"]
            assert str(row.objective.item()) in record["overrides"][0]
        # run_figures=auto: a sweep's job draws none (hybrid-sysid-report run_figures=true draws them later)
        assert not (job / "figures").exists()


def test_markdown_table_is_mean_and_spread_over_seeds(tiny_sweep):
    proc, sw = tiny_sweep
    md = (sw / "summary.md").read_text()
    table = next(block for block in md.split("\n\n") if block.startswith("| objective "))
    # the table is printed too, in a terminal's width (test_console.py): each of its cells
    assert all(cell.strip() in proc.stdout for line in table.splitlines()[2:] for cell in line.split("|")[1:-1])
    for objective in ("labelled", "hybrid"):
        vals = []
        for job in sw.iterdir():
            if (job / "metrics.json").exists():
                rec = json.loads((job / "metrics.json").read_text())
                if f"objective={objective}" in rec["overrides"]:
                    vals += [
                        r["mean_rel_dev"]
                        for r in rec["results"]
                        if r["split"] == "test" and r["noise_std"] == 0.0 and r["parameter"] == "p1"
                    ]
        cell = f"{100 * np.mean(vals):.2f} ± {100 * np.std(vals, ddof=1):.2f}"
        line = next(ln for ln in md.splitlines() if ln.startswith("|") and ln.split("|")[1].strip() == objective)
        shown = line.split("|")[2].strip().removesuffix(" †").split(" [")[0]  # marks: best, worse; interval
        assert shown.strip("*") == cell
    assert (sw / "figures" / "robustness.png").stat().st_size > 10_000


def test_report_rebuilds_the_same_table(tiny_sweep, tmp_path, monkeypatch):
    import runpy

    _, sw = tiny_sweep
    out = tmp_path / "report"
    # `python -m hybrid_sysid.report`, run in this process: its module, arguments and exit status, not a new process
    monkeypatch.setattr(sys, "argv", ["python -m hybrid_sysid.report", str(sw), f"out={out}"])
    with pytest.raises(SystemExit) as done:
        runpy.run_module("hybrid_sysid.report", run_name="__main__", alter_sys=True)
    assert done.value.code == 0
    assert (out / "summary.md").read_text().split("\n\n")[1:] == (sw / "summary.md").read_text().split("\n\n")[1:]
    pd.testing.assert_frame_equal(pd.read_csv(out / "summary.csv"), pd.read_csv(sw / "summary.csv"))


@started_early
def failing_sweep(tmp, env, tiny_cache):
    """A new process: the sweep ends in SystemExit with a message, which the interpreter prints and turns into exit
    status 1."""
    args = ["-m", "model.optim.lr=0.003,-1", *TINY, f"hydra.sweep.dir={tmp / 'sw'}"]
    return run_app(tmp, *args, cache=tiny_cache, env=env), tmp / "sw"


def test_a_failing_job_is_a_row_and_the_sweep_exits_nonzero(failing_sweep):
    proc, sw = failing_sweep
    assert proc.returncode != 0
    summary = pd.read_csv(sw / "summary.csv")
    failed = summary[summary.status == "failed"]
    assert len(failed) == 1 and "model.optim.lr = -1" in failed.error.item()
    assert (summary[summary.status == "completed"].run.nunique()) == 1
    assert "1 of 2 jobs failed" in proc.stderr + proc.stdout


@pytest.mark.slow  # test_faults.py's interrupted sweep and test_tuned.py's sweep launch through joblib by default
def test_joblib_launcher_runs_jobs_in_parallel_processes(tmp_path):
    proc = run_app(tmp_path, "-m", "launcher=joblib", "seed=0,1", *TINY, f"hydra.sweep.dir={tmp_path / 'sw'}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_csv(tmp_path / "sw" / "summary.csv")
    assert set(summary.status) == {"completed"} and summary.run.nunique() == 2
    assert "JoblibLauncher" in (tmp_path / "sw" / "multirun.yaml").read_text()


@pytest.mark.slow
def test_slurm_path_through_submitits_local_executor(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    proc = run_app(
        tmp_path,
        "-m",
        "launcher=submitit_local",
        "seed=0,1",
        *TINY,
        "trainer.max_steps=4",
        "trainer.eval_every_n_steps=2",
        f"hydra.sweep.dir={tmp_path / 'sw'}",
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_csv(tmp_path / "sw" / "summary.csv")
    assert set(summary.status) == {"completed"} and summary.run.nunique() == 2
    assert (tmp_path / "sw" / ".submitit").is_dir()


@pytest.mark.slow
def test_sweeps_started_together_get_their_own_directories(tmp_path):
    env = {**os.environ, "HYBRID_SYSID_CACHE": str(tmp_path / "cache")}
    args = [
        sys.executable,
        "-m",
        "hybrid_sysid",
        "-m",
        "seed=0",
        *TINY,
        "trainer.max_steps=2",
        "trainer.eval_every_n_steps=1",
    ]
    procs = [
        subprocess.Popen(args, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for _ in range(2)
    ]
    assert [p.wait(timeout=600) for p in procs] == [0, 0]
    sweeps = list((tmp_path / "outputs" / "multirun").iterdir())
    assert len(sweeps) == 2
    assert all((s / "summary.csv").exists() and (s / "0" / "metrics.json").exists() for s in sweeps)


@pytest.mark.slow  # test_faults.py interrupts a sweep and re-runs it in the default suite
def test_an_interrupted_sweep_completes_without_redoing_finished_jobs(tmp_path):
    import signal
    import time

    env = {**os.environ, "HYBRID_SYSID_CACHE": str(tmp_path / "cache")}
    args = [sys.executable, "-m", "hybrid_sysid", "-m", "seed=0,1", *TINY, f"hydra.sweep.dir={tmp_path / 'sw'}"]
    proc = subprocess.Popen(args, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first = tmp_path / "sw" / "0" / "metrics.json"
    deadline = time.time() + 300
    while not first.exists() and time.time() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not (tmp_path / "sw" / "summary.csv").exists()
    before = first.read_bytes()

    again = subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr[-2000:]
    assert "already completed" in again.stdout + again.stderr
    assert first.read_bytes() == before  # job 0 was not trained again
    summary = pd.read_csv(tmp_path / "sw" / "summary.csv")
    assert set(summary.status) == {"completed"} and summary.run.nunique() == 2
