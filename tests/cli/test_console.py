"""What the commands print: a sweep's one line per finished job and its table, a single run without a progress
bar in a log file, Lightning's messages once and in the run's log file, each command's --help, and the install
command of a missing extra for both kinds of install."""

import json
import os
import re
import sys

import pytest

from hybrid_sysid.launch.console import ConsoleFilter

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
    assert "mean relative deviation on the test split" in said and "\nhybrid " in said  # the sweep's table
    for noise in ("litlogger", "Seed set", "GPU available", "per road class", "LeafSpec", "INFO: "):
        assert noise not in said, noise  # no advert, Lightning's INFO and the runs' own tables in the log files
    assert not BAR.search(said)
    # 4 jobs of 2 table rows in under 40 lines: 2 at the start, Hydra's 1 and 2 a job (Hydra's and its own),
    # the table's 2 blocks of 5 lines (one per parameter) and its notes; each further job adds 2, each row 2
    assert len(lines) < 40, said
    repeated = [ln for ln in set(lines) if re.search(r"\w", ln) and lines.count(ln) > 1]
    assert not repeated, repeated  # no line said twice (a block's rule of dashes aside)
    # each network's end says it trained, so that a re-run of the sweep can time others by it (launch.time_left)
    ends = [json.loads(ln) for ln in (sweep_dir / ".progress").read_text().splitlines()[1:] if '"end"' in ln]
    assert sorted(e["end"] for e in ends if e.get("trained") is True) == [0, 1, 2, 3], ends
    # and the CPU time of its fit, by which kinds are compared: a process spends at most its cores x its wall time
    assert all(0 < e["cpu"] <= os.cpu_count() * e["work"] + 0.02 for e in ends), ends


def test_a_sweeps_table_fits_100_columns_and_holds_every_cell_of_summary_md(tiny_sweep):
    """The full table (summary.md) runs wider than a terminal; the console shows the same cells in blocks."""
    from helpers.evaluation_fakes import parse_markdown

    proc, sweep_dir = tiny_sweep
    table = proc.stdout[proc.stdout.index("mean relative deviation on the test split") :]
    assert max(len(line) for line in table.splitlines()) <= 100, table
    rows = parse_markdown((sweep_dir / "summary.md").read_text())
    assert len(rows) == 3  # hybrid, labelled and the Cramér-Rao bound
    for row in rows:
        for header, cell in row.items():
            if header != "objective":
                # the cell on its own row's line, in the block whose header names its column
                block = next(b for b in table.split("\n\n") if "---" in b and header in b.splitlines()[0])
                lines = [ln for ln in block.splitlines() if ln.startswith(row["objective"])]
                assert any(cell in ln for ln in lines), (row["objective"], header, cell, block)


@started_early
def single_run(tmp, env, tiny_cache):
    """A new process: progress_bar=auto asks the real stdout whether it is a terminal, and everything the process
    prints (Lightning's messages, an import's warnings) is what is tested. (its process, its run directory)"""
    return run_app(tmp, *TINY, f"hydra.run.dir={tmp / 'run'}", cache=tiny_cache, env=env), tmp / "run"


def test_a_single_run_into_a_file_prints_its_table_without_a_progress_bar(single_run):
    proc, _ = single_run
    assert proc.returncode == 0, proc.stderr[-2000:]
    said = proc.stdout + proc.stderr
    assert "p1 mean rel. dev. [%]" in said and "per road class" in said  # a single run prints its result
    assert not BAR.search(said) and "litlogger" not in said and "Seed set" not in said
    assert len(said) < 3000
    assert max(len(ln) for ln in said.splitlines() if not ln.startswith("[")) <= 100  # its tables, not log lines


def test_a_single_run_logs_each_message_once(single_run):
    log = (single_run[1] / "train.log").read_text()
    messages = [re.sub(r"^\[[^]]*\]", "", ln) for ln in log.splitlines() if ln.startswith("[")]
    assert len(messages) == len(set(messages)) and "loaded cached dataset" in log, log


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

    from hybrid_sysid.launch.console import job_running

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


def test_the_console_counts_in_the_singular_and_plural():
    from omegaconf import OmegaConf

    from hybrid_sysid.core.words import count
    from hybrid_sysid.launch.progress import start_line

    assert [count(n, "job") for n in (0, 1, 2)] == ["0 jobs", "1 job", "2 jobs"]
    assert count(1, "directory", "directories") == "1 directory" and count(3, "directory", "directories")[2:] == (
        "directories"
    )
    basic = "hydra._internal.core_plugins.basic_launcher.BasicLauncher"
    for jobs, threads, said in (
        (1, 1, "1 job, 1 at a time, 1 torch thread each"),
        (3, 2, "3 jobs, 1 at a time, 2 torch threads each"),
    ):
        config = OmegaConf.create({"hydra": {"launcher": {"_target_": basic}}, "trainer": {"threads": threads}})
        assert start_line(config, jobs, "sw").startswith(f"sweep: {said} into sw\n")


def test_a_job_line_estimates_the_time_left():
    import time
    from types import SimpleNamespace

    from hybrid_sysid.launch.progress import job_line

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

    from hybrid_sysid.launch import process as job

    text = None if direct_url is None else json.dumps(direct_url)
    monkeypatch.setattr(importlib.metadata, "distribution", lambda name: SimpleNamespace(read_text=lambda f: text))
    monkeypatch.setattr(job, "installed", lambda module: False)
    assert job.missing_extra(["hparams_search=fast_cnn"]) == (
        f"hparams_search=fast_cnn needs optuna, which is not installed: {install}"
    )
