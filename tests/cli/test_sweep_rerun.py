"""A command run again into a completed sweep's or run's directory: the same command skips what completed and
rewrites none of its files; another config, other overrides, or a sweep whose multirun.yaml cannot tell, is refused
in one line before any job starts. A swept choice whose package is missing is one line before any job. The sweep
and its runs are made once by a real process (started early); each test runs the command's main() in this
process on a copy of them (cli_in_process in conftest.py)."""

import shutil

import pytest
import yaml

from helpers import app_process
from helpers.started_early import started_early
from helpers.tree import snapshot

pytestmark = pytest.mark.integration

# a trainer preset of the user's own --config-dir, which a test changes between two commands
PRESET = "defaults:\n  - debug\n  - _self_\nmax_steps: 2\neval_every_n_steps: 1\nprogress_bar: false\n"
SWEEP = ["-m", "seed=0,1", "data=tiny", "trainer=mine"]


@started_early
def made_sweep(tmp, env, tiny_cache):
    """A two-job sweep made with a --config-dir: its directory and the config directory."""
    conf = tmp / "conf"
    (conf / "trainer").mkdir(parents=True)
    (conf / "trainer" / "mine.yaml").write_text(PRESET)
    sw = tmp / "sw"
    proc = app_process.run_app(tmp, "--config-dir", conf, *SWEEP, f"hydra.sweep.dir={sw}", cache=tiny_cache, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return sw, conf


@pytest.fixture
def copy(made_sweep, tmp_path):
    """A copy of the sweep (its files' times kept) and of its config directory, for a test to run commands on."""
    sw, conf = made_sweep
    shutil.copytree(sw, tmp_path / "sw")
    shutil.copytree(conf, tmp_path / "conf")
    return tmp_path / "sw", tmp_path / "conf"


def command(where, conf, *extra, mode="sweep"):
    """The sweep's command into ``where``; mode="run": its job 0 as a single run into ``where``."""
    if mode == "run":
        return ["--config-dir", conf, "seed=0", "data=tiny", "trainer=mine", *extra, f"hydra.run.dir={where}"]
    return ["--config-dir", conf, *SWEEP, *extra, f"hydra.sweep.dir={where}"]


def records(root):
    """What no command may change: each run's record and saved config, bytes and modification times."""
    return {p: v for p, v in snapshot(root).items() if "/.hydra/" in p or p.endswith("metrics.json")}


def what_ran(sw):
    """multirun.yaml's command-line overrides and the config its jobs were composed from."""
    saved = yaml.safe_load((sw / "multirun.yaml").read_text())
    return saved["hydra"]["overrides"]["task"], {k: v for k, v in saved.items() if k != "hydra"}


def one_line(code, err, *words):
    assert code == 2, err[-2000:]
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: "), err[-2000:]
    assert all(w in err for w in words), err


@pytest.mark.parametrize("mode", ["sweep", "run"])
def test_the_same_command_again_skips_the_completed_runs_and_rewrites_none_of_their_files(
    copy, mode, cli_in_process, tiny_cache
):
    from hybrid_sysid.cli.train import main

    sw, conf = copy
    where = sw if mode == "sweep" else sw / "0"
    before, multirun = records(sw), what_ran(sw)
    code, out, err = cli_in_process(main, *command(where, conf, mode=mode), cwd=sw.parent, env=env(tiny_cache))
    assert code == 0, err[-2000:]
    assert "already completed" in out + err
    assert records(sw) == before  # Hydra saved no .hydra/ over a completed run, not even the same text
    assert what_ran(sw) == multirun  # Hydra's sweeper saves it again: the same sweep (its paths may differ)


@pytest.mark.parametrize("mode", ["sweep", "run"])
def test_a_sweep_saved_before_a_key_existed_is_the_same_command_again(copy, mode, cli_in_process, tiny_cache):
    """multirun.yaml and the jobs' saved configs without ``tags``, as a sweep made before the key existed has
    them: its default ([]) is what they meant, so the command again skips the completed runs (it was refused,
    "tags: (absent) there, [] here")."""
    from hybrid_sysid.cli.train import main

    sw, conf = copy
    for saved in [sw / "multirun.yaml", *sw.glob("*/.hydra/config.yaml")]:
        values = yaml.safe_load(saved.read_text())
        assert values.pop("tags") == []
        values.pop("schema_version")  # saved before the schema had versions
        saved.write_text(yaml.safe_dump(values))
    where = sw if mode == "sweep" else sw / "0"
    code, out, err = cli_in_process(main, *command(where, conf, mode=mode), cwd=sw.parent, env=env(tiny_cache))
    assert code == 0, err[-2000:]
    assert "already completed" in out + err


@pytest.mark.parametrize("mode", ["sweep", "run"])
def test_a_changed_file_of_the_config_dir_is_refused_before_anything_is_written(copy, mode, cli_in_process, tiny_cache):
    from hybrid_sysid.cli.train import main

    sw, conf = copy
    where = sw if mode == "sweep" else sw / "0"
    (conf / "trainer" / "mine.yaml").write_text(PRESET.replace("max_steps: 2", "max_steps: 3"))
    before = snapshot(sw)
    code, _, err = cli_in_process(main, *command(where, conf, mode=mode), cwd=sw.parent, env=env(tiny_cache))
    key = "hydra.sweep.dir" if mode == "sweep" else "hydra.run.dir"
    one_line(code, err, f"{key} = {where} is not allowed", "another config (trainer.max_steps: 2 there, 3 here")
    assert snapshot(sw) == before


@pytest.mark.parametrize("damage", ["deleted", "emptied", "garbled"])
@pytest.mark.parametrize("same", [True, False], ids=["same overrides", "other overrides"])
def test_a_sweep_whose_multirun_yaml_cannot_tell_is_refused_whatever_the_command(
    copy, damage, same, cli_in_process, tiny_cache
):
    from hybrid_sysid.cli.train import main

    sw, conf = copy
    saved = sw / "multirun.yaml"
    if damage == "deleted":
        saved.unlink()
    else:
        saved.write_text("" if damage == "emptied" else "hydra: {overrides: [unclosed\n")
    before = snapshot(sw)
    extra = [] if same else ["model.optim.lr=0.002"]
    code, _, err = cli_in_process(main, *command(sw, conf, *extra), cwd=sw.parent, env=env(tiny_cache))
    one_line(code, err, "hydra.sweep.dir", "multirun.yaml is missing or damaged", "choose another hydra.sweep.dir")
    assert snapshot(sw) == before


def test_other_overrides_are_refused_before_anything_is_written(copy, cli_in_process, tiny_cache):
    from hybrid_sysid.cli.train import main

    sw, conf = copy
    before = snapshot(sw)
    code, _, err = cli_in_process(main, *command(sw, conf, "model.optim.lr=0.002"), cwd=sw.parent, env=env(tiny_cache))
    one_line(code, err, "hydra.sweep.dir", "holds a sweep of other overrides")
    assert snapshot(sw) == before


def env(cache):
    return {"HYBRID_SYSID_CACHE": cache}


@pytest.mark.parametrize(
    "sweep",
    [["logger=csv,mlflow", "objective=labelled,hybrid"], ["logger=mlflow", "objective=labelled,hybrid"]],
    ids=["swept", "fixed"],
)
def test_a_swept_choice_without_its_package_is_one_line_before_any_job(
    tmp_path, sweep, monkeypatch, cli_in_process, tiny_cache
):
    """mlflow is installed here: the check is told it is not, as a missing package would tell it."""
    import importlib.util

    from hybrid_sysid.cli.train import main
    from hybrid_sysid.launch import process

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "mlflow" else real(name, *a))
    assert not process.installed("mlflow")
    sw = tmp_path / "sw"
    args = ["-m", *sweep, "data=tiny", "trainer=debug", "trainer.max_steps=1", f"hydra.sweep.dir={sw}"]
    code, _, err = cli_in_process(main, *args, cwd=tmp_path, env=env(tiny_cache))
    one_line(code, err, "logger=mlflow needs mlflow, which is not installed: pip install")
    assert not sw.exists()


def test_a_sweep_directory_that_cannot_be_made_is_one_line(tmp_path, cli_in_process, tiny_cache):
    from hybrid_sysid.cli.train import main

    (tmp_path / "a_file").write_text("not a directory")
    sw = tmp_path / "a_file" / "sw"
    args = ["-m", "seed=0,1", "data=tiny", "trainer=debug", f"hydra.sweep.dir={sw}"]
    code, _, err = cli_in_process(main, *args, cwd=tmp_path, env=env(tiny_cache))
    one_line(code, err, f"hydra.sweep.dir = {sw} cannot be created", "NotADirectoryError")
    assert (tmp_path / "a_file").read_text() == "not a directory" and not (tmp_path / "outputs").exists()


@pytest.mark.parametrize("n_jobs", ["0", "two"])
def test_a_joblib_sweep_of_no_workers_is_one_line_before_its_directory(n_jobs, tmp_path, cli_in_process, tiny_cache):
    """joblib itself refuses n_jobs = 0 with a traceback, once the sweep directory and its lock are made."""
    from hybrid_sysid.cli.train import main

    sw = tmp_path / "sw"
    args = ["-m", "seed=0,1", "data=tiny", "trainer=debug", "launcher=joblib", f"hydra.launcher.n_jobs={n_jobs}"]
    code, _, err = cli_in_process(main, *args, f"hydra.sweep.dir={sw}", cwd=tmp_path, env=env(tiny_cache))
    if n_jobs == "two":  # Hydra's schema for the joblib launcher refuses a word at composition, also exit 2
        assert code == 2 and "Traceback" not in err and not sw.exists(), err[-2000:]
        return
    one_line(code, err, "hydra.launcher.n_jobs = 0 is not allowed")
    assert not sw.exists()
