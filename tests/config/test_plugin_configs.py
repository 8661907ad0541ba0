"""An installed package's configs are options like the project's own, without ``hydra.searchpath``: the package
declares the package of its configs in the entry point group hybrid_sysid.configs, and the search path plugin
this project ships (src/hydra_plugins/hybrid_sysid_configs) appends it to hybrid-sysid's search path. Another
Hydra app's search path never gets it; with no such package installed, or one that declares a package that is
not there, the config is what it was. tests/cli/test_plugin_data.py does the same through the command line."""

import sys

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.errors import MissingConfigException
from omegaconf import OmegaConf

from hybrid_sysid.config import CONF_DIR

from helpers.installed import install_package

# a package of configs alone: an option of the objective group, naming the project's own class with its own values
FILES = {
    "mylab/__init__.py": "",
    "mylab/conf/__init__.py": "",
    "mylab/conf/objective/scaled_l1.yaml": (
        "_target_: hybrid_sysid.model.objectives.LabelledObjective\np_scale: [3.0, 700.0]\n"
    ),
}
DECLARED = {"hybrid_sysid.configs": {"mylab": "mylab.conf"}}


@pytest.fixture
def installed(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(install_package(tmp_path / "site", "mylab", FILES, DECLARED)))
    yield
    for name in [m for m in sys.modules if m.split(".")[0] == "mylab"]:
        del sys.modules[name]


def search_path(config_dir) -> list[tuple[str, str]]:
    """(provider, path) of each element of the search path Hydra composes with for ``config_dir``."""
    with initialize_config_dir(config_dir=str(config_dir), version_base="1.3"):
        return [(e.provider, e.path) for e in GlobalHydra.instance().config_loader().get_search_path().get_path()]


def added(config_dir) -> list[str]:
    return [path for provider, path in search_path(config_dir) if provider.startswith("hybrid-sysid plugin")]


def test_an_installed_packages_option_composes_without_hydra_searchpath(installed, make_cfg):
    cfg = make_cfg("objective=scaled_l1")
    assert cfg.objective._target_ == "hybrid_sysid.model.objectives.LabelledObjective"
    assert list(cfg.objective.p_scale) == [3.0, 700.0]  # the package's file, not the project's labelled.yaml
    # after the project's own configs, so an option of the same name stays the project's
    providers = [provider for provider, _ in search_path(CONF_DIR)]
    assert providers.index("hybrid-sysid plugin mylab") > providers.index("main")
    assert added(CONF_DIR) == ["pkg://mylab.conf"]


def test_without_the_package_its_option_is_unknown_and_nothing_is_added(make_cfg):
    with pytest.raises(MissingConfigException):
        make_cfg("objective=scaled_l1")
    assert added(CONF_DIR) == []


def test_another_hydra_apps_search_path_gets_no_package_configs(installed, tmp_path):
    app = tmp_path / "app"
    (app / "objective").mkdir(parents=True)
    (app / "config.yaml").write_text("defaults:\n  - objective: own\n")
    (app / "objective" / "own.yaml").write_text("x: 1\n")
    assert added(app) == [] and not any("mylab" in path for _, path in search_path(app))
    with initialize_config_dir(config_dir=str(app), version_base="1.3"):
        with pytest.raises(MissingConfigException):
            compose(config_name="config", overrides=["objective=scaled_l1"])


def test_a_declared_package_of_configs_that_is_missing_changes_nothing(tmp_path, monkeypatch, make_cfg):
    before = OmegaConf.to_container(make_cfg(), resolve=True)
    declared = {"hybrid_sysid.configs": {"ghost": "ghost_lab.conf", "typo": "ghost lab/conf"}}
    monkeypatch.syspath_prepend(str(install_package(tmp_path / "site", "ghost-lab", {}, declared)))
    # a value that names no module is not given to Hydra; a module that is not there, Hydra skips
    assert added(CONF_DIR) == ["pkg://ghost_lab.conf"]
    assert OmegaConf.to_container(make_cfg(), resolve=True) == before
