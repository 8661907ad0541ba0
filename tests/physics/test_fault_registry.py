"""The registry of faults (physics.faults) is the one list the config section, the evaluation's overrides, the
docs table and the installed plugins' faults come from; a fault is declared once."""

import dataclasses
import sys
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from hybrid_sysid.config.schema import SensorConfig
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.core.options import EVAL_OVERRIDABLE, FIXES
from hybrid_sysid.physics.faults import (
    GROUP,
    Fault,
    Gain,
    Setting,
    fix_code,
    fixes,
    register,
    register_installed,
    registered,
    settings,
    table,
    unregister,
)
from hybrid_sysid.physics.faults import registry as registry_module

ROOT = Path(__file__).resolve().parents[2]
DOCS = (ROOT / "docs" / "faults.md").read_text()
PLUGIN_DIR = ROOT / "tests" / "plugins" / "faults"
OWN = [f for f in registered() if type(f).__module__.startswith("hybrid_sysid.")]


def test_the_docs_table_lists_every_fault_of_the_package_with_its_default():
    assert table(OWN) in DOCS
    rows = {line.split(" | ")[0][2:]: line.split(" | ") for line in DOCS.splitlines() if line.startswith("| `")}
    for s in (s for f in OWN for s in f.settings):
        assert rows[f"`{s.key}`"][3] == ("`null`" if s.default is None else f"`{s.default:g}`"), s.key


def test_the_docs_example_is_the_plugin_that_the_tests_register():
    section = DOCS[DOCS.index("## Adding a fault") :]
    python = section.split("```python\n", 1)[1].split("```", 1)[0]
    yaml = section.split("```yaml\n", 1)[1].split("```", 1)[0]
    assert python == (PLUGIN_DIR / "offset_fault.py").read_text()
    assert yaml == (PLUGIN_DIR / "fault" / "offset.yaml").read_text()
    assert 25 <= len(python.splitlines()) <= 40  # a complete example of about 30 lines


def test_the_config_section_is_made_of_the_sensor_faults_settings(make_cfg):
    schema = {f.name: f.default for f in dataclasses.fields(SensorConfig)}
    assert schema == {name: s.default for name, s in settings("sensor").items()}
    # conf/sensor/none.yaml repeats none of them: the composed default is the settings' defaults
    assert OmegaConf.to_container(make_cfg().sensor) == schema


def test_an_evaluation_may_change_every_fault_setting():
    assert {s.section for s in settings().values()} <= set(EVAL_OVERRIDABLE)


def test_each_fault_names_a_classical_fix_the_fixed_fits_know():
    assert {f.fix for f in registered()} <= set(FIXES)
    # the package's own fixes are its faults' code, in the order core.options lists them
    assert fixes() == FIXES
    assert [fix_code(name).name for name in FIXES[1:]] == list(FIXES[1:]) and fix_code("none") is None


class Again(Fault):
    name = "again"
    settings = (Setting("gain_spread", 0.0, "the gain's key, declared a second time"),)


def test_a_fault_or_a_key_is_declared_once():
    with pytest.raises(ValueError, match="'gain'"):
        register(Gain)
    with pytest.raises(ValueError, match="sensor.gain_spread of fault 'gain'"):
        register(Again)
    assert "again" not in {f.name for f in registered()}


def test_an_installed_package_declares_its_fault_by_an_entry_point(monkeypatch):
    monkeypatch.syspath_prepend(str(PLUGIN_DIR))
    points = [EntryPoint("offset", "offset_fault:Offset", GROUP)]
    monkeypatch.setattr(registry_module, "entry_points", lambda group: points if group == GROUP else [])
    register_installed()
    try:
        assert [f.name for f in registered()][-1] == "offset" and "offset_std" in settings("sensor")
        register_installed()  # read again: registered once
        assert [f.name for f in registered()].count("offset") == 1
    finally:
        unregister("offset")
        sys.modules.pop("offset_fault", None)


def test_an_installed_fault_whose_import_fails_is_one_line_naming_its_entry_point(monkeypatch):
    monkeypatch.setattr(
        registry_module, "entry_points", lambda group: [EntryPoint("broken", "no_such_module:X", GROUP)]
    )
    with pytest.raises(ConfigError) as caught:
        register_installed()
    text = str(caught.value)
    assert "hybrid_sysid.faults:broken" in text and "ModuleNotFoundError" in text and "\n" not in text
