"""A run directory is data, not code: a config whose _target_ names anything but this package's classes (or
Lightning's loggers) is refused in one line, by every command that reads a run, before the target is imported."""

import pickle
import shutil
import subprocess
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from hybrid_sysid.config import ConfigError, validate


class Touch:
    """A pickle whose loading creates a file: what pandas.read_pickle would run."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return Path.touch, (Path(self.path),)


def planted(tiny_run, tmp_path, key, node) -> Path:
    """A copy of a trained run whose saved config has ``node`` at ``key``."""
    run = tmp_path / "received_run"
    shutil.copytree(tiny_run, run)
    cfg = OmegaConf.load(run / ".hydra" / "config.yaml")
    OmegaConf.update(cfg, key, node, merge=False)
    OmegaConf.save(cfg, run / ".hydra" / "config.yaml")
    return run


def payloads(tmp_path):
    """(key, node, the file it would create) for each planted payload."""
    marker = tmp_path / "pickle_ran"
    (tmp_path / "x.pkl").write_bytes(pickle.dumps(Touch(marker)))
    return [
        ("objective", {"_target_": "pandas.read_pickle", "filepath_or_buffer": str(tmp_path / "x.pkl")}, marker),
        ("model.net", {"_target_": "numpy.save", "file": str(tmp_path / "saved"), "arr": [1]}, tmp_path / "saved.npy"),
        (
            "objective",
            {
                "_target_": "hybrid_sysid.model.objectives.HybridObjective",
                "filter": {"_target_": "pathlib.Path.touch", "self": str(tmp_path / "nested")},
            },
            tmp_path / "nested",
        ),
    ]


@pytest.mark.parametrize("case", [0, 1, 2], ids=["read_pickle", "numpy.save", "nested"])
def test_load_estimator_refuses_a_planted_target_and_runs_nothing(tiny_run, tmp_path, case):
    from hybrid_sysid import load_estimator

    key, node, marker = payloads(tmp_path)[case]
    run = planted(tiny_run, tmp_path, key, node)
    with pytest.raises(ValueError, match=rf"{key}(\.\w+)?\._target_ = '[\w.]+' is not allowed"):
        load_estimator(run)
    assert not marker.exists()


@pytest.mark.parametrize("case", [0, pytest.param(1, marks=pytest.mark.slow)], ids=["read_pickle", "numpy.save"])
def test_evaluation_refuses_a_planted_target_before_anything_runs(tiny_run, tmp_path, case, cli_in_process):
    # the command's main() in this process, without HYDRA_FULL_ERROR (the user's view: no traceback); an evaluation
    # refused in a real process:
    # tests/experiments/test_transfer.py::test_eval_cli_sweeps_cars_and_refuses_another_objective
    from hybrid_sysid.cli.evaluate import main as evaluate

    key, node, marker = payloads(tmp_path)[case]
    run = planted(tiny_run, tmp_path, key, node)
    out = tmp_path / "eval"
    cli = [evaluate, f"run={run}", "car=soft_seat", f"hydra.run.dir={out}"]
    proc = subprocess.CompletedProcess(cli, *cli_in_process(*cli, cwd=tmp_path))
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert f"{key}._target_" in proc.stderr and "is not allowed" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not marker.exists() and not out.exists()


@pytest.mark.parametrize(
    "override, match",
    [
        ("+logger.x._target_=os.getcwd", r"logger.x._target_ = 'os.getcwd' is not allowed"),
        ("objective._target_=builtins.print", r"objective._target_ = 'builtins.print' is not allowed"),
        ("model.net._target_=os.system", r"model.net._target_ = 'os.system' is not allowed"),
    ],
)
def test_a_command_line_target_outside_the_package_is_refused(make_cfg, override, match):
    with pytest.raises(ConfigError, match=match):
        validate(make_cfg(override))


def test_predict_refuses_a_planted_target_in_one_line(tiny_run, tmp_path, capsys):
    from hybrid_sysid.cli.predict import main

    key, node, marker = payloads(tmp_path)[0]
    run = planted(tiny_run, tmp_path, key, node)
    (tmp_path / "rec.csv").write_text(
        "time,seat_acc,body_acc\n" + "".join(f"{i * 0.005},0.1,0.2\n" for i in range(400))
    )
    with pytest.raises(SystemExit) as exit_:
        main([f"run={run}", f"input={tmp_path / 'rec.csv'}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2 and len(err) == 1, err
    assert "objective._target_ = 'pandas.read_pickle' is not allowed" in err[0] and not marker.exists()
