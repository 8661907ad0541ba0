"""A data module of another installed package (entry point group hybrid_sysid.datasets) named at data.module: the
checks before any work allow only a class that package declares there, build it, and refuse in one line naming the
key a class that lacks a member of DataModule (model/base.py), an object that does not set one, a window other
than data.window, a run it cannot serve (a baseline, an objective reading band-passed signals) and a constructor
that raises. A run records the class, and its saved config opened where the package is missing names the package.
tests/cli/test_plugin_data.py trains on the example package's data module."""

import sys
import textwrap

import pytest

from hybrid_sysid.config import validate
from hybrid_sysid.config.targets import check_saved, data_module, plugin_fields
from hybrid_sysid.core.checks import ConfigError

from helpers.installed import install_package

# every member of DataModule, without Lightning (the checks build it, and a run would hand it to Lightning)
FULL = """
class LabData:
    def __init__(self, window=200, gain=1.0):
        if gain <= 0:
            raise ValueError(f"gain = {gain} must be positive")
        self.window, self.gain, self.dataset = window, gain, None

    def setup(self, stage=None): ...
    def train_dataloader(self): ...
    def val_dataloader(self): ...
    def rows(self, split): ...
    def eval_batch(self, split, noise_std=0.0, limit=None, windows=1): ...
    def eval_dataloader(self, split, noise_std=0.0, limit=None, windows=1): ...
"""
NO_EVALUATION = FULL.split("    def eval_batch")[0]  # trains, but offers the evaluation no fixed windows
NO_DATASET = FULL.replace("self.window, self.gain, self.dataset = window, gain, None", "self.window = window")
TARGET = "lab_data.LabData"
# its config, which the package declares too: data=tiny's recordings' keys (data.window = 200, the class's default)
LAB_YAML = f"defaults:\n  - tiny\n  - _self_\nmodule:\n  _target_: {TARGET}\n"
DATA = ["data=lab"]


@pytest.fixture
def install(tmp_path, monkeypatch):
    """``install(source, group)``: the module lab_data of ``source``, its class declared in ``group``."""

    def _install(source, group="hybrid_sysid.datasets"):
        files = {"lab_data.py": textwrap.dedent(source), "lab_conf/__init__.py": "", "lab_conf/data/lab.yaml": LAB_YAML}
        declared = {group: {"lab": "lab_data:LabData"}, "hybrid_sysid.configs": {"lab": "lab_conf"}}
        monkeypatch.syspath_prepend(str(install_package(tmp_path / "site", "lab-data", files, declared)))

    yield _install
    for name in ("lab_data", "lab_conf"):
        sys.modules.pop(name, None)


def refusal(make_cfg, *overrides) -> str:
    with pytest.raises(ConfigError) as err:
        validate(make_cfg(*overrides))
    message = str(err.value)
    assert "\n" not in message
    return message


def test_a_declared_data_module_is_built_from_its_own_arguments(install, make_cfg):
    install(FULL)
    cfg = make_cfg(*DATA, "+data.module.gain=2.5")
    validate(cfg)
    dm = data_module(cfg)
    assert type(dm).__name__ == "LabData" and (dm.window, dm.gain) == (200, 2.5)
    assert plugin_fields(cfg)["plugins"]["data.module"] == {
        "class": TARGET,
        "entry_point": "hybrid_sysid.datasets:lab",
        "package": "lab-data",
        "version": "0.1.0",
    }


def test_a_class_declared_in_another_group_is_refused_before_its_module_is_imported(install, make_cfg, tmp_path):
    marker = tmp_path / "imported"
    install(f"open({str(marker)!r}, 'w').close()\n" + FULL, group="hybrid_sysid.networks")
    message = refusal(make_cfg, *DATA)
    assert message.startswith(f"data.module._target_ = '{TARGET}' is not allowed: a class of hybrid_sysid.data or")
    assert "none declares it in the entry point group hybrid_sysid.datasets" in message
    assert not marker.exists() and "lab_data" not in sys.modules


@pytest.mark.parametrize(
    "source, words",
    [
        (NO_EVALUATION, "a class with eval_batch, eval_dataloader (DataModule of hybrid_sysid.model.base"),
        (NO_DATASET, "a class whose objects have dataset (DataModule, model/base.py)"),
    ],
)
def test_a_data_module_lacking_a_member_is_one_line_naming_it(install, make_cfg, source, words):
    install(source)
    message = refusal(make_cfg, *DATA)
    assert message.startswith(f"data.module._target_ = '{TARGET}' is not allowed: {words}"), message


@pytest.mark.parametrize(
    "overrides, start",
    [
        (["+data.module.window=100"], "data.module.window = 100 is not allowed: data.window = 200"),
        (["+data.module.gain=-1"], "data.module is not allowed: ValueError: gain = -1 must be positive"),
        (["+data.module.depth=3"], "data.module.depth = 3 is not allowed: not an argument of LabData, which takes"),
        (["+data.module.dt=0.01"], "data.module.dt = 0.01 is not allowed: the recordings' step, data.dt = 0.005"),
        (
            ["baseline=ls_bandpass"],
            f"data.module._target_ = '{TARGET}' is not allowed: none with baseline= (a baseline reads",
        ),
        (
            ["objective=hybrid_bandpass"],
            "objective._target_ = 'hybrid_sysid.model.objectives.HybridObjective' is not allowed: an objective "
            "without fir: the batches of data.module carry no band-passed signals",
        ),
    ],
)
def test_what_a_data_module_cannot_serve_is_one_line_naming_the_key(install, make_cfg, overrides, start):
    install(FULL)
    message = refusal(make_cfg, *DATA, *overrides)
    assert message.startswith(start), message


def test_a_run_made_with_a_data_module_names_its_package_where_it_is_missing(make_cfg):
    cfg = make_cfg("data=tiny")  # the saved config of a run made with the package, opened where it is missing
    cfg.data.module = {"_target_": TARGET}
    made = {"class": TARGET, "entry_point": "hybrid_sysid.datasets:lab", "package": "lab-data", "version": "0.1.0"}
    with pytest.raises(ConfigError) as err:
        check_saved(cfg, {"plugins": {"data.module": made}})
    assert str(err.value).startswith(f"data.module._target_ = '{TARGET}' is not allowed: ")
    assert "hybrid_sysid.datasets:lab of the package lab-data 0.1.0, not installed here: pip install lab-data" in str(
        err.value
    )


def test_the_command_refuses_a_data_module_lacking_a_member_in_one_line_making_nothing(
    install, cli_in_process, tmp_path
):
    from hybrid_sysid.cli.train import main

    install(NO_EVALUATION)
    code, out, err = cli_in_process(main, *DATA, "trainer=debug", "hydra.run.dir=run", cwd=tmp_path)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err[-2000:]
    assert lines[0].startswith(f"error: data.module._target_ = '{TARGET}' is not allowed: a class with eval_batch")
    assert not (tmp_path / "run").exists() and not (tmp_path / "outputs").exists()


def test_the_simulators_data_module_meets_the_contract(make_cfg):
    """DataModule declares what the run reads of the project's own data module: its class and a built one have it
    all (the protocol names no member the simulator's module lacks)."""
    from hybrid_sysid.config.targets import known_class
    from hybrid_sysid.model.base import DataModule, lacks
    from hybrid_sysid.training.build import build_datamodule

    cls = known_class("hybrid_sysid.data.datamodule.QuarterCarDataModule", "data.module")
    assert lacks(cls, DataModule) == ["window", "dataset"]  # set by the constructor: checked on the object
    assert lacks(build_datamodule(make_cfg("data=tiny")), DataModule) == []
