"""A received run directory is data: its saved config gets the checks of a command line before predict estimates
with it (hybrid_sysid.inference.loading), in one line, exit status 2, nothing written."""

import os
import resource
import shutil
import subprocess
import sys

import numpy as np
import pytest

from helpers.estimator_run import predict
from helpers.hostile import laughs
from helpers.received import received
from helpers.started_early import started_early
from helpers.tree import snapshot


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A recording sampled at twice the run's rate (data=tiny: dt 0.005 s), so resample=true has work to do."""
    path = tmp_path_factory.mktemp("recording") / "drive.csv"
    t = np.arange(4000) * 0.0025
    columns = np.c_[t, np.sin(9 * t), np.cos(7 * t)]
    np.savetxt(path, columns, delimiter=",", header="time,seat_acc,body_acc", comments="")
    return path


@pytest.mark.parametrize(
    "line, replaced, words",
    [
        ("  window: 200", "  window: 0", "data.window = 0 is not allowed"),  # was a reshape traceback
        ("  dt: 0.005", "  dt: 0", "data.dt = 0.0 is not allowed"),  # was a ZeroDivisionError with resample=true
    ],
)
def test_a_received_runs_values_get_a_command_lines_checks(
    tiny_run, tmp_path, recording, capsys, line, replaced, words
):
    run = received(tiny_run, tmp_path, line, replaced)
    before = snapshot(tmp_path, recording.parent)
    code, out, err = predict(capsys, f"run={run}", f"input={recording}", "resample=true")
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and f"run = {run}: {words}" in err, err
    assert snapshot(tmp_path, recording.parent) == before


def test_a_billion_laughs_in_a_saved_config_is_one_line_at_once(tiny_run, tmp_path, cli_in_process):
    """Chained aliases in .hydra/config.yaml (once: eval ran 7.5 min at 2.2 GB) are refused by their expanded
    size before OmegaConf builds anything; eval's preflight says so in one line, exit 2, nothing written."""
    from hybrid_sysid.cli.evaluate import main as evaluate

    run = tmp_path / "received"
    shutil.copytree(tiny_run, run)
    with open(run / ".hydra" / "config.yaml", "a") as f:
        f.write(laughs(6, 10))  # a million leaves: seconds and a few hundred MB, expanded
    before = snapshot(tmp_path)
    code, out, err = cli_in_process(evaluate, f"run={run}", f"hydra.run.dir={tmp_path / 'ev'}", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert "config.yaml is damaged" in err and "nodes with its aliases expanded" in err, err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["predict", "eval", "report"])
def test_a_saved_config_whose_aliases_expand_to_megabytes_is_refused_at_once(
    tiny_run, tmp_path, recording, capfd, cli_in_process, command
):
    """One long scalar aliased (the attack: 8 MiB, 90,000 times, once hours of CPU deaf to SIGTERM; here 700 kB
    twice, so the test ends without the bound too). predict and eval refuse it in one line, exit 2, nothing
    written; the report tabulates the run from its record alone, as with any unreadable config."""
    run = tmp_path / "received"
    shutil.copytree(tiny_run, run)
    with open(run / ".hydra" / "config.yaml", "a") as f:
        f.write("big: &b " + "a" * 700_000 + "\nmany: [*b, *b]\n")
    before = snapshot(tmp_path, recording.parent)
    if command == "report":
        from hybrid_sysid.cli.report import main as report

        assert report([str(run), f"out={tmp_path / 'out'}"]) == 0
        out, err = capfd.readouterr()
        assert "Traceback" not in err and (tmp_path / "out" / "summary.md").is_file()
        return
    if command == "predict":
        from hybrid_sysid.cli.predict import main as predict_main

        code, out, err = cli_in_process(predict_main, f"run={run}", f"input={recording}", cwd=tmp_path)
    else:
        from hybrid_sysid.cli.evaluate import main as evaluate

        code, out, err = cli_in_process(evaluate, f"run={run}", f"hydra.run.dir={tmp_path / 'ev'}", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert f"run = {run} is not allowed: its .hydra/config.yaml is damaged" in err
    assert "bytes of text with its aliases expanded" in err and "aaaa" not in err
    assert snapshot(tmp_path, recording.parent) == before


@pytest.mark.parametrize("kind", ["nested", "fifo"])
def test_a_damaged_metrics_json_leaves_the_runs_error_unknown(tiny_run, tmp_path, recording, capsys, kind):
    """metrics.json nested 100,000 deep (once a RecursionError named as the config's) or a FIFO (once a
    reader waiting forever): the run estimates, its test error unknown (flag run_error)."""
    run = tmp_path / "received"
    shutil.copytree(tiny_run, run)
    record = run / "metrics.json"
    record.unlink()
    if kind == "fifo":
        os.mkfifo(record)
    else:
        record.write_text("[" * 100_000 + "]" * 100_000)
    code, out, err = predict(capsys, f"run={run}", f"input={recording}", "resample=true")
    assert code == 0, err
    assert "run_error" in out and "test error is unknown" in err, err


def test_a_device_as_the_input_is_one_line_without_reading_it(tiny_run, tmp_path):
    """input=/dev/zero (once read until memory ran out: a MemoryError) is refused before any read, here under
    an address-space limit that reading it would exceed."""
    proc = subprocess.run(
        [sys.executable, "-m", "hybrid_sysid.cli.predict", f"run={tiny_run}", "input=/dev/zero"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (6 * 2**30, 6 * 2**30)),
    )
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr[-2000:]
    assert "input = /dev/zero is not allowed: a regular file" in proc.stderr
    assert list(tmp_path.iterdir()) == []


@started_early
def escaped_prediction(tmp, env, tiny_run):
    """A recording named sitz_ä predicted under LC_ALL=C without UTF-8 mode: (the process, its output CSV)."""
    path = tmp / "drive.csv"
    t = np.arange(2000) * 0.005
    rows = "".join(f"sitz_ä,{ti},{np.sin(9 * ti)},{np.cos(7 * ti)}\n" for ti in t)
    path.write_text("recording,time,seat_acc,body_acc\n" + rows, encoding="utf-8")
    env = {k: v for k, v in env.items() if k not in ("PYTHONIOENCODING", "HYDRA_FULL_ERROR")}
    env.update(LC_ALL="C", LANG="C", PYTHONUTF8="0")
    out = tmp / "estimates.csv"
    proc = subprocess.run(
        [sys.executable, "-m", "hybrid_sysid.cli.predict", f"run={tiny_run}", f"input={path}", f"output={out}"],
        cwd=tmp,
        env=env,
        capture_output=True,
        timeout=300,
    )
    return proc, out


def test_non_ascii_names_under_an_ascii_locale_print_escaped(escaped_prediction):
    """Once a UnicodeEncodeError traceback, exit 1: the table prints the name escaped, the output CSV keeps it as
    UTF-8."""
    proc, out = escaped_prediction
    assert proc.returncode == 0 and b"Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert b"sitz_\\xe4" in proc.stdout
    assert out.read_text(encoding="utf-8").splitlines()[1].startswith("sitz_ä,")


def test_a_report_counts_a_metrics_json_nested_deep_as_unreadable(tiny_run, tmp_path, capsys):
    """Once a RecursionError traceback: now the run is one of the report's unreadable runs (exit 1)."""
    from hybrid_sysid.cli.report import main

    run = tmp_path / "received"
    shutil.copytree(tiny_run, run)
    (run / "metrics.json").write_text("[" * 100_000 + "]" * 100_000)
    assert main([str(run), f"out={tmp_path / 'out'}"]) == 1
    assert "1 run, 1 failed or unreadable" in capsys.readouterr().err


@started_early
def report_in_non_ascii_directory(tmp, env, tiny_cache):
    """A run in lauf_ü, then the report of it, under LC_ALL=C without UTF-8 mode: (their processes, lauf_ü)."""
    where = tmp / "lauf_ü"
    where.mkdir()
    env = {k: v for k, v in env.items() if k not in ("PYTHONIOENCODING", "HYDRA_FULL_ERROR")}
    env.update(LC_ALL="C", LANG="C", PYTHONUTF8="0", HYBRID_SYSID_CACHE=str(tiny_cache))
    # the run's directory under the working directory (outputs/runs/<time>), so no argument holds the name
    commands = [
        [sys.executable, "-m", "hybrid_sysid", "baseline=ls_window", "data=tiny"],
        [sys.executable, "-m", "hybrid_sysid.report", "outputs/runs"],
    ]
    procs = [subprocess.run(command, cwd=where, env=env, capture_output=True, timeout=300) for command in commands]
    return procs, where


def test_a_run_and_its_report_in_a_non_ascii_directory_under_an_ascii_locale(report_in_non_ascii_directory):
    """Once a 40-line logging traceback: exit 0, no logging error, the log file keeps the path's bytes as they were
    (UTF-8), and the report of the run writes its summary."""
    procs, where = report_in_non_ascii_directory
    for proc in procs:
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert b"Logging error" not in proc.stderr and b"Traceback" not in proc.stderr, proc.stderr[-2000:]
    (run,) = (where / "outputs" / "runs").glob("*/metrics.json")
    assert "lauf_ü".encode() in (run.parent / "train.log").read_bytes()
    assert (where / "outputs" / "runs" / "summary.md").is_file()


@pytest.mark.parametrize(
    "line, replaced, key",
    [
        ("  train_std: 0.0", "  train_std: 1.0e+300", "noise.train_std"),
        ("  threads: null", "  threads: 1000000000000000000000000000000", "trainer.threads"),
        ("    n_layers: 4", "    n_layers: abc", "model.net.n_layers"),
        ("  seat_hardening: 0.0", "  seat_hardening: .inf", "car.seat_hardening"),
        ("    lr: 0.02", "    lr: 1.0e+300", "model.optim.lr"),
        ("  window: 200", "  window: -1", "data.window"),
        ("  c2: 4741.0", "  c2: 1.0e+300", "car.c2"),
        ("  extra: {}", "  extra: {max_epochs: -5}", "trainer.extra"),
    ],
)
def test_hostile_values_in_a_received_config_stop_the_eval_command_in_one_line(
    tiny_run, tmp_path, cli_in_process, line, replaced, key
):
    """hybrid-sysid-eval of a received run whose saved config holds a hostile value: one line naming the key,
    exit 2, nothing written (neither in the run nor where the evaluation would go)."""
    from hybrid_sysid.cli.evaluate import main

    run = received(tiny_run, tmp_path, line, replaced)
    before = snapshot(tmp_path)
    code, out, err = cli_in_process(main, f"run={run}", f"hydra.run.dir={tmp_path / 'ev'}", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert err.startswith("error: ") and key in err, err
    assert snapshot(tmp_path) == before
