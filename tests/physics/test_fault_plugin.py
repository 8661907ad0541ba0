"""A fault added from outside the package (tests/plugins/faults/offset_fault.py, the example of docs/faults.md):
once registered it is drawn from the dataset's fault stream, added to the channels, keyed in the cache on its own
and checked by its declared range, like the package's own faults, against the offset added by hand."""

import dataclasses
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hybrid_sysid.config.schema import sensor_section
from hybrid_sysid.config.versions import VERSION, upgraded
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data.cache import cache_path, get_dataset
from hybrid_sysid.data.dataset import FAULT_STREAM, fault_draws, generate_dataset
from hybrid_sysid.data.spec import DatasetSpec
from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.faults import SensorFaults, fix_for, register, unregister

PLUGIN = Path(__file__).resolve().parents[1] / "plugins" / "faults" / "offset_fault.py"
SMALL = dict(n_roads=3, n_masses=4, n_steps=300, seat_spread=0.2)
STD = 0.01
PRESETS = {  # the package's faults, whose keys registering another fault must leave as they were
    "none": {},
    "gain": {"gain_spread": 0.03},
    "skewed": {"skew_max": 0.01},
    "lowpass": {"lowpass_range_hz": (20.0, 40.0)},
}


@pytest.fixture
def before_offset():
    """The presets' keys before the offset fault is registered; then registered, and taken out at the end."""
    keys = {name: DatasetSpec(**SMALL, sensor=SensorFaults(**v)).key() for name, v in PRESETS.items()}
    loader = importlib.util.spec_from_file_location("offset_fault", PLUGIN)
    module = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(module)
    register(module.Offset)
    yield keys
    unregister("offset")


def offsets_by_hand(spec: DatasetSpec) -> np.ndarray:
    """(n, 2) offsets: the dataset's fault stream [seed, FAULT_STREAM] after the unit draws of the package's three
    sensor faults (gains (n, 2), skews (n,), cut-offs (n, 2)), then a standard normal (n, 2) times the std."""
    n = spec.n_roads * spec.n_masses
    rng = np.random.default_rng([spec.seed, FAULT_STREAM])
    rng.uniform(size=(n, 2)), rng.uniform(size=n), rng.uniform(size=(n, 2))
    return STD * rng.standard_normal((n, 2))


def float32_margin(*arrays) -> float:
    """Two float32 roundings (the stored reference's and the result's) at the largest magnitude, with a factor 2."""
    return 4 * float(np.spacing(np.float32(max(np.abs(a).max() for a in arrays))))


@pytest.mark.parametrize("gain", [0.0, 0.03])
def test_the_offset_is_drawn_and_added_to_each_sensor(before_offset, gain):
    """With the gain on too, the offset acts after it: gain times the true acceleration, plus the offset."""
    base = DatasetSpec(**SMALL, sensor=SensorFaults(gain_spread=gain))
    spec = DatasetSpec(**SMALL, sensor=SensorFaults(gain_spread=gain, offset_std=STD))
    clean, ds = generate_dataset(base), generate_dataset(spec)
    off = offsets_by_hand(spec)
    np.testing.assert_array_equal(fault_draws(spec)["offset"], off)
    np.testing.assert_array_equal(fault_draws(spec).gains, fault_draws(base).gains)  # the other faults' draws stay
    np.testing.assert_array_equal(ds.params, clean.params)  # the same recordings, the labels unchanged
    seat, body = clean.seat_acc + off[:, :1], clean.body_acc + off[:, 1:]
    np.testing.assert_allclose(ds.seat_acc, seat, rtol=0, atol=float32_margin(seat))
    np.testing.assert_allclose(ds.body_acc, body, rtol=0, atol=float32_margin(body))
    # the regressors are integrated again from the recorded channels: relative_states is linear in them
    ramp = relative_states(np.broadcast_to(off[:, :1], seat.shape), np.broadcast_to(off[:, 1:], seat.shape), spec.dt)
    for got, was, added in zip((ds.rel_vel, ds.rel_disp), (clean.rel_vel, clean.rel_disp), ramp):
        np.testing.assert_allclose(got, was + added, rtol=0, atol=float32_margin(was, was + added))
    assert np.abs(ds.seat_acc - clean.seat_acc).max() > 100 * float32_margin(seat)  # the offset is there


def test_the_offset_is_keyed_on_its_own_and_others_keep_theirs(before_offset, tmp_path):
    after = {name: DatasetSpec(**SMALL, sensor=SensorFaults(**v)).key() for name, v in PRESETS.items()}
    assert after == before_offset
    spec = DatasetSpec(**SMALL, sensor=SensorFaults(offset_std=STD))
    other = DatasetSpec(**SMALL, sensor=SensorFaults(offset_std=2 * STD))
    assert len({spec.key(), other.key(), *after.values()}) == len(after) + 2
    ds = get_dataset(spec, tmp_path)
    assert cache_path(spec, tmp_path).is_file() and not cache_path(DatasetSpec(**SMALL), tmp_path).exists()
    again = get_dataset(spec, tmp_path)  # read back from its own file
    np.testing.assert_array_equal(again.seat_acc, ds.seat_acc)
    assert SensorFaults() == DatasetSpec(**SMALL).sensor  # one made before the registration equals one after


@pytest.mark.parametrize("value", [-0.01, 1.5, float("nan")])
def test_the_offset_is_checked_by_its_declared_range(before_offset, value):
    with pytest.raises(ConfigError) as caught:
        DatasetSpec(**SMALL, sensor=SensorFaults(offset_std=value)).validate()
    assert "sensor.offset_std" in str(caught.value) and "[0, 1]" in str(caught.value)
    assert "\n" not in str(caught.value)


def test_the_offset_joins_the_config_section_and_the_fix_choice(before_offset):
    section = {f.name: f.default for f in dataclasses.fields(sensor_section())}
    assert section["offset_std"] == 0.0 and "gain_spread" in section
    assert fix_for({"offset_std": STD}, {}) == "none"  # its own fix: none
    assert fix_for({"offset_std": STD, "gain_spread": 0.03}, {}) == "gain"
    # a run saved before the fault existed lacks its key and ran without it: read as its default (config.versions)
    assert upgraded({"schema_version": VERSION})["sensor.offset_std"] == 0.0


def test_an_unregistered_fault_is_no_setting():
    with pytest.raises(TypeError, match="offset_std"):
        SensorFaults(offset_std=STD)


# a process of its own: the fault registered before hybrid_sysid.config is imported, as an installed package's is,
# so the config's schema has its key and conf/fault/offset.yaml (here tests/plugins/faults/fault/) composes
COMMAND_LINE = """
import json, sys
sys.path.insert(0, sys.argv[1])
from offset_fault import Offset
from hybrid_sysid.physics.faults import register
register(Offset)
from hydra import compose, initialize_config_dir
from hybrid_sysid.config import CONF_DIR, ConfigError, validate
from hybrid_sysid.data.spec import DatasetSpec
out = {}
with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
    for name, overrides in (("preset", ["fault=offset"]), ("bad", ["sensor.offset_std=-1"]), ("clean", [])):
        cfg = compose("config", overrides=["data=tiny", f"hydra.searchpath=[file://{sys.argv[1]}]", *overrides])
        try:
            validate(cfg, training=False)
            out[name] = [cfg.sensor.offset_std, DatasetSpec.from_config(cfg).key()]
        except ConfigError as exc:
            out[name] = str(exc)
print(json.dumps(out))
"""


def test_a_fault_registered_first_is_a_config_key_with_its_preset_and_its_check():
    done = subprocess.run(
        [sys.executable, "-c", COMMAND_LINE, str(PLUGIN.parent)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.splitlines()[-1])
    assert out["preset"][0] == 0.01 and out["clean"][0] == 0.0
    assert out["preset"][1] != out["clean"][1]
    assert out["bad"].startswith("sensor.offset_std = -1") and "[0, 1]" in out["bad"] and "\n" not in out["bad"]
