"""What the commands print: a sweep's one line per finished job and its table, a single run without a progress
bar in a log file, Lightning's messages once and in the run's log file, each command's --help, and the install
command of a missing extra for both kinds of install."""

import json
import re
import sys

import pytest

from hybrid_sysid.cli.console import ConsoleFilter

from helpers.app_process import run_app
from helpers.started_early import started_early

TINY = ["data=tiny", "trainer=debug"]
BAR = re.compile(r"it/s|\r|█")


def test_a_sweep_prints_a_line_per_job_and_its_table(tiny_sweep):
    proc, sweep_dir = tiny_sweep  # 2 objectives x 2 seeds, its output captured (conftest.py)
    assert proc.returncode == 0, proc.stderr[-2000:]
    said = proc.stdout + proc.stderr
    lines = said.splitlines()
    assert lines[0].startswith(f"sweep: 4 jobs, 1 at a time into {sweep_dir}")
    job = r"\[\d/4\] #\d objective=(labelled|hybrid) seed=\d: p1 [\d.]+ %, p2 [\d.]+ % \(test, noise 0"
    done = [line for line in lines if re.match(job, line)]
    assert [d[:8] for d in done] == ["[1/4] #0", "[2/4] #1", "[3/4] #2", "[4/4] #3"], said
    # an estimate of the time left until the last
    assert all("left" in d for d in done[:-1]) and "left" not in done[-1]
    assert "mean relative deviation on the test split" in said and "| hybrid " in said  # the sweep's table
    for noise in ("litlogger", "Seed set", "GPU available", "per road class", "LeafSpec", "INFO: "):
        assert noise not in said, noise  # no advert, Lightning's INFO and the runs' own tables in the log files
    assert not BAR.search(said)
    # under 20 lines for 2 jobs of one table row; each further job adds 2 (Hydra's line and its own), each
    # further row 1
    assert len(lines) < 20 + 2 * 2 + 1, said


def test_a_sweep_job_logs_everything_once_into_its_own_file(tiny_sweep):
    _, sweep_dir = tiny_sweep
    log = (sweep_dir / "0" / "train.log").read_text()
    assert log.count("Seed set to 0") == 1 and log.count("GPU available") == 1  # once: no duplicate handler
    assert "per road class" in log and "litlogger" not in log
    assert json.loads((sweep_dir / ".progress").read_text().splitlines()[0])["jobs"] == 4


@started_early
def single_run(tmp, env, tiny_cache):
    """A new process: progress_bar=auto asks the real stdout whether it is a terminal, and everything the process
    prints (Lightning's messages, an import's warnings) is what is tested."""
    return run_app(tmp, *TINY, f"hydra.run.dir={tmp / 'run'}", cache=tiny_cache, env=env)


def test_a_single_run_into_a_file_prints_its_table_without_a_progress_bar(single_run):
    proc = single_run
    assert proc.returncode == 0, proc.stderr[-2000:]
    said = proc.stdout + proc.stderr
    assert "p1 mean rel. dev. [%]" in said and "per road class" in said  # a single run prints its result
    assert not BAR.search(said) and "litlogger" not in said and "Seed set" not in said
    assert len(said) < 3000


def test_progress_bar_auto_draws_only_on_a_terminal(monkeypatch, make_cfg):
    from hybrid_sysid.config import validate
    from hybrid_sysid.core.checks import ConfigError
    from hybrid_sysid.training.build import progress_bar_on

    monkeypatch.setattr(sys.stdout, "isatty", lambda: True)
    assert progress_bar_on("auto") and progress_bar_on(True) and not progress_bar_on(False)
    monkeypatch.setattr(sys.stdout, "isatty", lambda: False)
    assert not progress_bar_on("auto") and progress_bar_on(True)
    with pytest.raises(ConfigError, match=r"^trainer.progress_bar = 'yes' is not allowed: true, false or auto"):
        validate(make_cfg("data=tiny", "trainer.progress_bar=yes"))


def test_the_console_filter_keeps_a_sweeps_jobs_quiet():
    import logging

    from hybrid_sysid.cli.console import job_running

    def shown(filter_, name, level, msg):
        return filter_.filter(logging.LogRecord(name, level, __file__, 1, msg, (), None))

    run, sweep = ConsoleFilter("RunMode.RUN"), ConsoleFilter("RunMode.MULTIRUN")
    with job_running():
        assert not shown(run, "lightning.fabric.utilities.seed", logging.INFO, "Seed set to 0")
        assert shown(run, "lightning.pytorch.utilities.rank_zero", logging.WARNING, "a warning")
        assert shown(run, "hybrid_sysid", logging.INFO, "run %s: %s\n%s")
        assert not shown(sweep, "hybrid_sysid", logging.INFO, "run %s: %s\n%s")  # a job's table: its log file
        assert shown(sweep, "hybrid_sysid", logging.WARNING, "job failed: %s")
        assert shown(sweep, "hybrid_sysid.data.cache", logging.INFO, "simulating %d roads")
        assert shown(sweep, "hybrid_sysid", logging.INFO, "run %s already completed; not running it again")
    assert shown(sweep, "hybrid_sysid", logging.INFO, "search: best trial %d")  # the sweep's own, not a job's


def test_a_job_line_estimates_the_time_left():
    import time
    from types import SimpleNamespace

    from hybrid_sysid.cli.progress import job_line

    header = {"jobs": 9, "swept": ["objective", "seed"], "start": time.time() - 60}
    record = {"status": "completed", "results": [
        {"split": "test", "noise_std": n, "windows": k, "parameter": p, "mean_rel_dev": 0.1 + n}
        for n in (0.0, 0.1) for k in (1, 8) for p in ("p1", "p2")
    ]}  # fmt: skip
    ret = SimpleNamespace(overrides=["objective=hybrid", "seed=1", "data=tiny"], return_value=record)
    line = job_line(header, 3, 4, ret, 41.0)
    assert line.startswith("[3/9] #4 objective=hybrid seed=1: p1 10.00 %, p2 10.00 % (test, noise 0, K=1) in 41 s")
    assert line.endswith("sweep 1:00, about 2:00 left")
    failed = SimpleNamespace(overrides=["seed=2"], return_value={"status": "failed", "error": "ValueError: x"})
    assert "failed (ValueError: x)" in job_line({"jobs": 2, "start": time.time()}, 2, 1, failed, 1.0)


@pytest.mark.parametrize("command", ["hybrid_sysid", "hybrid_sysid.cli.evaluate"])
def test_help_of_the_hydra_commands_says_what_they_do(tmp_path, command, cli_in_process):
    # the command's main(), which `python -m` runs, in this process: the help ends before any work, and stdout
    # holds only what Hydra's help prints (an import's warnings would go to stderr)
    from hybrid_sysid.cli import evaluate, train

    main = train.main if command == "hybrid_sysid" else evaluate.main
    code, out, _ = cli_in_process(main, "--help", cwd=tmp_path)
    name = "hybrid-sysid" if command == "hybrid_sysid" else "hybrid-sysid-eval"
    assert code == 0 and out.startswith(f"{name}: ")
    assert "powered by Hydra" not in out and "Examples:" in out and "usage: " in out


def test_help_of_predict_and_report_and_their_key_value_errors(capsys):
    from hybrid_sysid.cli import predict, report

    predict.main(["--help"])
    out = capsys.readouterr().out
    assert out.startswith("hybrid-sysid-predict: estimate p1") and "example:" in out
    assert report.main(["-h"]) == 0 and capsys.readouterr().out.startswith("hybrid-sysid-report: rebuild")
    with pytest.raises(SystemExit) as exit_:
        predict.main(["--run=outputs/runs/x", "input=a.csv"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "is not allowed: key=value without dashes (run=outputs/runs/x)" in err


@pytest.mark.parametrize(
    "direct_url, install",
    [
        ({"url": "file:///src/hybrid-sysid", "dir_info": {"editable": True}}, 'pip install -e ".[search]"'),
        ({"url": "file:///w/hybrid_sysid-0.1.whl", "archive_info": {}}, 'pip install "hybrid-sysid[search]"'),
        (None, 'pip install "hybrid-sysid[search]"'),  # from an index: no direct_url.json
    ],
)
def test_a_missing_extra_names_the_install_command_of_this_install(monkeypatch, direct_url, install):
    import importlib.metadata
    from types import SimpleNamespace

    from hybrid_sysid.cli import process as job

    text = None if direct_url is None else json.dumps(direct_url)
    monkeypatch.setattr(importlib.metadata, "distribution", lambda name: SimpleNamespace(read_text=lambda f: text))
    monkeypatch.setattr(job, "installed", lambda module: False)
    assert job.missing_extra(["hparams_search=fast_cnn"]) == (
        f"hparams_search=fast_cnn needs optuna, which is not installed: {install}"
    )
