"""The command itself on bad values of issue 46: exit 2, one line on stderr naming the key, no traceback, and
no directory or file made, under the working directory or at the filesystem's root."""

from pathlib import Path

import pytest

CASES = [
    (["noise.train_std=1e300"], {}, "noise.train_std"),
    (["trainer.threads=100000"], {}, "trainer.threads"),
    (["trainer.devices=0"], {}, "trainer.devices"),
    (["car.seat_hardening=1e30"], {}, "car.seat_hardening"),
    (["objective=nonexistent"], {}, "objective"),
    (["trainer.max_steps=abc"], {}, "trainer.max_steps"),
    (["paths.root=''"], {}, "paths.root"),
    ([], {"HYBRID_SYSID_CACHE": ""}, "paths.cache_dir"),
    (["-m", "--cfg", "job"], {}, "the command line"),  # Hydra's own refusal of the pair, once a traceback
    (["baseline=null"], {}, "baseline"),  # null is no option to Hydra: it refused it unnamed, with a traceback
    (["baseline={a:1}"], {}, "baseline"),  # a dict merged into a null section: OmegaConf's AttributeError
]


@pytest.mark.parametrize("args, env, key", CASES)
def test_a_bad_value_is_one_line_naming_its_key_and_makes_nothing(tmp_path, cli_in_process, args, env, key):
    from hybrid_sysid.cli.train import main

    work = tmp_path / "work"
    work.mkdir()
    env = {"HYBRID_SYSID_CACHE": tmp_path / "cache", **env}
    code, out, err = cli_in_process(main, "data=tiny", "trainer=debug", *args, cwd=work, env=env)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err[-2000:]
    assert lines[0].startswith(f"error: {key} "), lines[0]
    assert list(work.iterdir()) == [] and not (tmp_path / "cache").exists()


EDGES = ["noise.train_std=0", "noise.eval_std=[0]", "trainer.threads=1", "car.seat_hardening=0", "seed=4294967295"]


def test_values_at_the_edge_of_their_ranges_train_and_record(tmp_path, cli_in_process, tiny_cache):
    """Values at an end of what the checks allow, in one run: exit 0 and a completed record that holds them."""
    import json

    from hybrid_sysid.cli.train import main

    args = ["data=tiny", "trainer=debug", "trainer.max_steps=2", *EDGES, f"hydra.run.dir={tmp_path / 'run'}"]
    code, out, err = cli_in_process(main, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 0, err[-2000:]
    record = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert record["status"] == "completed" and record["seed"] == 4294967295 and record["threads"] == 1
    assert {r["noise_std"] for r in record["results"]} == {0.0}
    assert all(r["mean_rel_dev"] >= 0 for r in record["results"])


def test_a_preset_of_the_joblib_launcher_run_with_launcher_basic_composes(tmp_path, cli_in_process, tiny_cache):
    """P50 (docs/reliability/adversarial_physical_limit.md): experiment=anchored_clean launcher=basic failed on the
    preset's joblib n_jobs. It now composes with Hydra's basic launcher: the sweep's first check after composing,
    the estimator's (an objective= beside its swept estimator), is what refuses it, before any directory."""
    from omegaconf import OmegaConf

    from hybrid_sysid.cli.train import main
    from hybrid_sysid.config import CONF_DIR

    swept = OmegaConf.load(f"{CONF_DIR}/experiment/anchored_clean.yaml").hydra.sweeper.params.estimator  # the preset's
    sweep = tmp_path / "sweep"
    args = ["-m", "experiment=anchored_clean", "launcher=basic", "objective=hybrid", f"hydra.sweep.dir={sweep}"]
    code, _, err = cli_in_process(main, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 2 and err.startswith(f"error: estimator = '{swept}'"), err[-2000:]
    assert not sweep.exists() and not (tmp_path / "outputs").exists()


def test_the_anchored_presets_keep_the_joblib_launchers_two_jobs():
    import yaml
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR

    joblib = yaml.safe_load((Path(CONF_DIR) / "launcher" / "joblib.yaml").read_text())["hydra"]["launcher"]
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        for name in ("anchored", "anchored_clean"):
            launcher = compose("config", [f"experiment={name}"], return_hydra_config=True).hydra.launcher
            assert launcher._target_.endswith("JoblibLauncher") and launcher.n_jobs == joblib["n_jobs"] == 2
            basic = compose("config", [f"experiment={name}", "launcher=basic"], return_hydra_config=True)
            assert basic.hydra.launcher._target_.endswith("BasicLauncher") and "n_jobs" not in basic.hydra.launcher


@pytest.mark.parametrize(
    "args",
    [
        ["-m", "experiment=tuned", "launcher=basic"],  # the preset sets the joblib launcher's n_jobs: 3
        ["-m", "launcher=basic", "hydra.launcher.n_jobs=3"],
    ],
)
def test_a_joblib_key_beside_another_launcher_is_one_line_naming_it_and_the_way_out(tmp_path, cli_in_process, args):
    from hybrid_sysid.cli.train import main

    code, _, err = cli_in_process(main, *args, f"hydra.sweep.dir={tmp_path / 'sweep'}", cwd=tmp_path)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err[-2000:]
    assert lines[0].startswith("error: hydra.launcher.n_jobs is not allowed: ") and "launcher=joblib" in lines[0]
    assert list(tmp_path.iterdir()) == []
