"""A preflight check that cannot complete stops the command in one line (exit 2) before any directory is made:
Hydra would only warn about a callback's exception and run the job unchecked (hybrid_sysid.launch.job)."""

import shutil
import subprocess

import pytest

from helpers.app_process import run_app
from helpers.tree import snapshot

TINY = ["data=tiny", "trainer=debug", "trainer.max_steps=5", "trainer.progress_bar=false"]


def one_line_refusal(proc, *words):
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr[-2000:]
    assert all(w in lines[0] for w in words), lines[0]
    assert "Traceback" not in proc.stderr + proc.stdout and "Warning" not in proc.stderr


@pytest.fixture
def cut_run(tmp_path, tiny_run):
    """A copy of the trained run whose saved config is cut at a line's end after the network's section: it
    still parses, the objective and trainer sections are gone."""
    run = tmp_path / "received"
    shutil.copytree(tiny_run, run)
    lines = (run / ".hydra" / "config.yaml").read_text().splitlines(keepends=True)
    cut = next(i for i, line in enumerate(lines) if line.startswith("objective:"))
    (run / ".hydra" / "config.yaml").write_text("".join(lines[:cut]))
    return run


def test_eval_of_a_run_whose_saved_config_is_cut_is_one_line_and_writes_nothing(tmp_path, cut_run):
    before = snapshot(tmp_path)
    proc = run_app(tmp_path, f"run={cut_run}", f"hydra.run.dir={tmp_path / 'ev'}", module="hybrid_sysid.cli.evaluate")
    one_line_refusal(proc, "run =", "saved config is complete", "trainer")
    assert snapshot(tmp_path) == before


def test_a_check_that_raises_anything_stops_the_command_before_any_directory(tmp_path, monkeypatch, cli_in_process):
    """Any exception of a check (here a MemoryError, as an absurd data.n_roads once raised in it) is one line,
    exit 2, and nothing is made: not the run directory, its lock or Hydra's .hydra/."""
    import hybrid_sysid.cli.train as train

    def broken(cfg):
        raise MemoryError("Unable to allocate 9.3 TiB for an array")

    monkeypatch.setattr(train, "validate", broken)
    before = snapshot(tmp_path)
    code, out, err = cli_in_process(
        train.main, *TINY, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tmp_path}
    )
    one_line_refusal(subprocess.CompletedProcess([], code, out, err), "could not complete", "MemoryError")
    assert snapshot(tmp_path) == before


def test_a_sweep_whose_check_raises_anything_stops_before_its_directory(tmp_path, monkeypatch, cli_in_process):
    import hybrid_sysid.launch.job as job
    from hybrid_sysid.cli.train import main

    def broken(*args, **kwargs):
        raise RecursionError("maximum recursion depth exceeded")

    monkeypatch.setattr(job, "make_dir", broken)
    before = snapshot(tmp_path)
    code, out, err = cli_in_process(
        main,
        "-m",
        "seed=0,1",
        *TINY,
        f"hydra.sweep.dir={tmp_path / 'sw'}",
        cwd=tmp_path,
    )
    one_line_refusal(subprocess.CompletedProcess([], code, out, err), "could not complete", "RecursionError")
    assert snapshot(tmp_path) == before
