"""The optional, git-ignored config group ``local`` (this machine's settings, as lightning-hydra-template's
configs/local/): absent, the composition is the one without it; present in the package's conf/ (a clone) or in the
user's config folder ($XDG_CONFIG_HOME/hybrid-sysid, an installed package), its values take effect as the same
command-line overrides would, below the command line. ``local/launcher/<launcher>.yaml`` applies with its launcher
alone. Each config folder here is a copy of the package's, so a developer's own local/ never enters the tests."""

import shutil
import subprocess
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from hybrid_sysid.config import CONF_DIR

LOCAL_ENTRIES = ("  - optional local@_global_: default\n", "  - optional local/launcher@_global_: ${launcher}\n")


def conf_copy(root: Path, with_local_entries: bool = True) -> Path:
    """The package's configs copied to ``root``/hybrid_sysid/conf (its local/ left out); without the entries, the
    defaults list as it was before the group existed: the reference an absent local/ must equal."""
    conf = root / "hybrid_sysid" / "conf"
    shutil.copytree(CONF_DIR, conf, ignore=lambda d, names: ["local"] if Path(d) == Path(CONF_DIR) else [])
    if not with_local_entries:
        text = (conf / "config.yaml").read_text()
        for entry in LOCAL_ENTRIES:
            assert entry in text  # the entries this test removes are the ones config.yaml has
            text = text.replace(entry, "")
        (conf / "config.yaml").write_text(text)
    return conf


def job(conf: Path, *overrides, hydra: bool = False):
    with initialize_config_dir(config_dir=str(conf), version_base="1.3"):
        cfg = compose(config_name="config", overrides=list(overrides), return_hydra_config=hydra)
    return cfg if hydra else OmegaConf.to_container(cfg, resolve=True)


@pytest.fixture
def confs(tmp_path, monkeypatch):
    """(the package's configs, the same without the local entries), and an empty user config home."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "home"))
    return conf_copy(tmp_path / "with"), conf_copy(tmp_path / "without", with_local_entries=False)


MACHINE = {"paths": {"root": "/scratch/me/outputs"}, "trainer": {"threads": 3}, "data": {"cache_dir": "/scratch/c"}}
AS_OVERRIDES = ["paths.root=/scratch/me/outputs", "trainer.threads=3", "data.cache_dir=/scratch/c"]


def write(path: Path, values: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(OmegaConf.to_yaml(values))


@pytest.mark.parametrize("overrides", [[], ["experiment=robustness"], ["launcher=slurm", "debug=fast"]])
def test_without_a_local_folder_the_composition_is_unchanged(confs, overrides):
    with_entries, without = confs
    assert job(with_entries, *overrides) == job(without, *overrides)


@pytest.mark.parametrize("where", ["package", "user"])
def test_local_default_takes_effect_as_the_same_overrides_would(confs, tmp_path, where):
    with_entries, without = confs
    folder = with_entries if where == "package" else tmp_path / "home" / "hybrid-sysid"
    write(folder / "local" / "default.yaml", MACHINE)
    cfg = job(with_entries)
    assert cfg == job(without, *AS_OVERRIDES)
    assert cfg["paths"]["runs_dir"].startswith("/scratch/me/outputs/")  # what reads paths.root follows it
    # the command line still wins over this machine's settings
    assert job(with_entries, "trainer.threads=1")["trainer"]["threads"] == 1


def test_the_package_s_local_folder_wins_over_the_user_s(confs, tmp_path):
    with_entries, _ = confs
    write(with_entries / "local" / "default.yaml", {"trainer": {"threads": 3}})
    write(tmp_path / "home" / "hybrid-sysid" / "local" / "default.yaml", {"trainer": {"threads": 5}})
    assert job(with_entries)["trainer"]["threads"] == 3


def test_a_launcher_s_local_settings_apply_with_that_launcher_alone(confs, tmp_path):
    with_entries, without = confs
    cluster = {"account": "mylab", "qos": "normal", "setup": ["module load python/3.11"]}
    write(tmp_path / "home" / "hybrid-sysid" / "local" / "launcher" / "slurm.yaml", {"hydra": {"launcher": cluster}})
    launcher = job(with_entries, "launcher=slurm", hydra=True).hydra.launcher
    assert {k: OmegaConf.to_container(launcher)[k] for k in cluster} == cluster
    # with another launcher (whose config has no such keys) nothing changes
    assert job(with_entries, "launcher=joblib") == job(without, "launcher=joblib")
    assert job(with_entries) == job(without)


def test_the_user_folder_is_searched_for_hybrid_sysid_s_configs_alone(tmp_path, monkeypatch):
    """Hydra runs the search-path plugin for every app in the environment: another app's optional local group
    never finds hybrid-sysid's user folder."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "home"))
    write(tmp_path / "home" / "hybrid-sysid" / "local" / "default.yaml", {"seed": 2})
    other = tmp_path / "other_app" / "conf"
    other.mkdir(parents=True)
    (other / "config.yaml").write_text("defaults:\n  - _self_\n  - optional local@_global_: default\nseed: 1\n")
    assert job(other) == {"seed": 1}
    assert job(conf_copy(tmp_path / "ours"))["seed"] == 2  # the same file, found for hybrid-sysid's configs


def test_the_local_folder_is_ignored_by_git():
    repo = Path(CONF_DIR).parents[2]
    if shutil.which("git") is None or not (repo / ".git").exists():
        pytest.skip("not a git checkout")
    for name in ("default.yaml", "launcher/slurm.yaml"):
        path = Path(CONF_DIR) / "local" / name
        out = subprocess.run(["git", "check-ignore", "-q", str(path)], cwd=repo, capture_output=True)
        assert out.returncode == 0, f"{path} is not git-ignored"
