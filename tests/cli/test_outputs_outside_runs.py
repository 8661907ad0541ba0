"""An output never lands inside a run or sweep directory (one holding .hydra/, multirun.yaml or metrics.json, or
under one): hybrid-sysid-report's results= and out=, hybrid-sysid-predict's output=, even with overwrite=true. One
line, exit status 2, every file of the run and the sweep as it was."""

import shutil

import numpy as np
import pytest
from omegaconf import OmegaConf

from helpers.estimator_run import predict
from helpers.tree import snapshot


@pytest.fixture
def run_and_sweep(tmp_path, tiny_run):
    """A copy of the trained run, and a sweep directory of one job (its multirun.yaml and the run)."""
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    sweep = tmp_path / "sweep"
    shutil.copytree(tiny_run, sweep / "0")
    (sweep / "multirun.yaml").write_text("hydra:\n  mode: MULTIRUN\n")
    return run, sweep


@pytest.mark.parametrize(
    "target",
    ["run/metrics.json", "run/checkpoints/best.ckpt", "run/new.md", "sweep/multirun.yaml", "sweep/pages"],
)
def test_report_results_inside_a_run_or_sweep_is_refused(tmp_path, run_and_sweep, capsys, target):
    from hybrid_sysid.cli.report import main

    run, sweep = run_and_sweep
    before = snapshot(tmp_path)
    code = main([str(run), f"results={tmp_path / target}"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"results = {tmp_path / target} is not allowed: it lies inside the run or sweep directory" in err
    assert snapshot(tmp_path) == before


def test_report_out_inside_another_run_is_refused_but_its_own_path_is_the_default(tmp_path, run_and_sweep, capsys):
    from hybrid_sysid.cli.report import main

    run, sweep = run_and_sweep
    before = snapshot(tmp_path)
    assert main([str(run), f"out={sweep / '0'}"]) == 2
    assert "out = " in capsys.readouterr().err and snapshot(tmp_path) == before
    assert main([str(sweep), f"out={sweep}"]) == 0  # a PATH itself: where its summary goes without out=
    assert (sweep / "summary.md").is_file()


@pytest.mark.parametrize("target", ["sweep/multirun.yaml", "sweep/0/metrics.json", "sweep/table.csv"])
def test_predict_output_inside_a_sweep_is_refused_even_with_overwrite(tmp_path, run_and_sweep, capsys, target):
    run, sweep = run_and_sweep
    recording = tmp_path / "drive.csv"
    t = np.arange(2000) * 0.005
    np.savetxt(recording, np.c_[t, np.sin(9 * t), np.cos(7 * t)], delimiter=",", header="time,seat_acc,body_acc")
    recording.write_text(recording.read_text().lstrip("# "))
    before = snapshot(tmp_path)
    code, out, err = predict(
        capsys, f"run={run}", f"input={recording}", f"output={tmp_path / target}", "overwrite=true"
    )
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "it lies inside the run or sweep directory" in err and str(sweep) in err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "key, target",
    [
        ("hydra.run.dir", "run/checkpoints/ev"),  # once a whole evaluation there, and two runs in its report
        ("hydra.run.dir", "sweep/0/ev"),
        ("hydra.run.dir", "sweep/ev"),
        ("hydra.sweep.dir", "run/sw"),
    ],
)
def test_eval_inside_another_run_or_sweep_is_refused_before_any_work(
    tmp_path, run_and_sweep, cli_in_process, key, target
):
    from hybrid_sysid.cli.evaluate import main

    run, sweep = run_and_sweep
    before = snapshot(tmp_path)
    args = [f"run={run}", f"{key}={tmp_path / target}", *(["-m"] if key == "hydra.sweep.dir" else [])]
    code, out, err = cli_in_process(main, *args, cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert f"{key} = {tmp_path / target} is not allowed: it lies inside the run or sweep directory" in err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "key, target",
    [
        ("hydra.run.dir", "run/checkpoints/tr"),  # once a whole run trained there, and two runs in its report
        ("hydra.run.dir", "sweep/0/tr"),
        ("hydra.run.dir", "sweep/tr"),
        ("hydra.sweep.dir", "run/sw"),
    ],
)
def test_training_inside_another_run_or_sweep_is_refused_before_any_work(
    tmp_path, run_and_sweep, cli_in_process, key, target
):
    from hybrid_sysid.cli.train import main

    before = snapshot(tmp_path)
    args = ["data=tiny", "trainer=debug", "trainer.max_steps=2", f"{key}={tmp_path / target}"]
    code, out, err = cli_in_process(main, *args, *(["-m"] if key == "hydra.sweep.dir" else []), cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert f"{key} = {tmp_path / target} is not allowed: it lies inside the run or sweep directory" in err
    assert snapshot(tmp_path) == before


def test_a_sweeps_job_resumed_in_its_sweep_directory_is_not_refused(tmp_path, run_and_sweep, cli_in_process):
    """resume= of a sweep's job: its directory lies in the sweep's (multirun.yaml), as every job's does. The
    completed job is skipped, none of its files written (the lock and the log are the command's own)."""
    from hybrid_sysid.cli.train import main

    from helpers.estimator_run import TINY

    run, sweep = run_and_sweep
    cache = OmegaConf.load(run / ".hydra" / "config.yaml").data.cache_dir
    before = snapshot(tmp_path)
    code, out, err = cli_in_process(main, *TINY, f"data.cache_dir={cache}", f"resume={sweep / '0'}", cwd=tmp_path)
    assert code == 0, err[-2000:]
    assert "inside the run or sweep directory" not in err
    after = snapshot(tmp_path)
    assert {p: after[p] for p in before if not after[p][0]} == {p: v for p, v in before.items() if not v[0]}
