"""The launcher presets: a parallel launcher gives each job one torch thread (docs/reliability/reproducibility.md),
so parallel jobs share the cores instead of each taking them all; the basic launcher keeps torch's default."""

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR


def composed(*overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides), return_hydra_config=True)


@pytest.mark.parametrize(
    "launcher, target",
    [
        ("joblib", "hydra_plugins.hydra_joblib_launcher.joblib_launcher.JoblibLauncher"),
        ("submitit_local", "hydra_plugins.hydra_submitit_launcher.submitit_launcher.LocalLauncher"),
    ],
)
def test_the_parallel_launcher_presets_set_one_torch_thread(launcher, target):
    cfg = composed(f"launcher={launcher}")
    assert cfg.hydra.launcher._target_ == target  # the preset chose the launcher it is named after
    assert cfg.trainer.threads == 1


def test_the_basic_launcher_keeps_torchs_default_thread_count():
    cfg = composed()
    assert cfg.hydra.launcher._target_ == "hydra._internal.core_plugins.basic_launcher.BasicLauncher"
    assert cfg.trainer.threads is None  # null: torch's default, every core


def test_the_experiments_on_joblib_keep_one_thread_a_job():
    experiments = [
        p.stem for p in sorted((Path(CONF_DIR) / "experiment").glob("*.yaml")) if "/launcher: joblib" in p.read_text()
    ]
    assert experiments  # the presets that run their jobs in parallel
    for name in experiments:
        cfg = composed(f"experiment={name}")
        assert "JoblibLauncher" in cfg.hydra.launcher._target_, name
        assert cfg.trainer.threads == 1, name
