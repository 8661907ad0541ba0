"""Promises of docs/reliability/run.md a command keeps on its console and in its log file: the warning of a resume
that cannot compare the configs, HYDRA_FULL_ERROR's traceback, figures that cannot be drawn. Each command runs its
main() in this process (cli_in_process in conftest.py)."""

import json
import os
import shutil
import subprocess
import sys

import pytest

pytestmark = pytest.mark.faults


def test_a_resume_whose_saved_config_cannot_be_read_warns_on_stderr_and_in_train_log(
    tiny_run, tmp_path, cli_in_process
):
    """The run resumes as promised (from its last checkpoint, to a completed record), and the warning that the
    configs were not compared is one line on stderr and a line of the run's train.log."""
    from hybrid_sysid.cli.train import main

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    (run / "metrics.json").unlink()  # killed after its last checkpoint: resume= continues it
    (run / ".hydra" / "config.yaml").write_text("data: {n_roads: [\n")
    args = ["data=tiny", "trainer=debug", "trainer.max_steps=400", "trainer.progress_bar=false", f"resume={run}"]
    code, out, err = cli_in_process(main, *args, "run_figures=false", cwd=tmp_path)
    assert code == 0, err[-2000:]
    assert json.loads((run / "metrics.json").read_text())["status"] == "completed"
    warning = f"{run}/.hydra/config.yaml cannot be read (UnreadableFile: "
    shown = [line for line in err.splitlines() if warning in line]
    assert len(shown) == 1 and shown[0].startswith("warning: ") and "without comparing the configs" in shown[0]
    logged = [line for line in (run / "train.log").read_text().splitlines() if warning in line]
    assert len(logged) == 1 and "[WARNING]" in logged[0] and "without comparing the configs" in logged[0]
    assert warning not in out  # once on the console: not again among the job's lines


def test_hydra_full_error_shows_the_traceback(tmp_path):
    """An unknown key, with HYDRA_FULL_ERROR=1: the traceback behind Hydra's message (without it: one message,
    exit 2, no traceback, tests/config/test_config.py). A real process: the interpreter prints it."""
    env = {**os.environ, "HYDRA_FULL_ERROR": "1"}
    cli = [sys.executable, "-m", "hybrid_sysid", "data.n_road=3", f"hydra.run.dir={tmp_path / 'run'}"]
    proc = subprocess.run(cli, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0 and not (tmp_path / "run").exists()
    assert "Traceback (most recent call last)" in proc.stderr and "Key 'n_road' not in 'DataConfig'" in proc.stderr


def test_a_runs_figures_that_cannot_be_drawn_are_a_warning(tmp_path, monkeypatch, caplog):
    """Drawing a run's figures (after its record is written) fails: a warning naming the run, no exception."""
    import hybrid_sysid.report.run_figures as run_figures
    from hybrid_sysid.launch.job import draw_run_figures

    def broken(run_dir):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(run_figures, "write_run_figures", broken)
    draw_run_figures(tmp_path)
    assert f"run figures not drawn in {tmp_path}: OSError: [Errno 28] No space left on device" in caplog.text
    assert any(r.levelname == "WARNING" for r in caplog.records)
