"""Sensor faults in the dataset (data.sensor): off by default with the old cache key and data, drawn per recording
from the dataset's seed, equal to the numpy path (physics.sensors.apply, then relative_states), every sample
interpolated from true samples, and the config's presets and refusals."""

import numpy as np
import pytest

from hybrid_sysid.config import ConfigError, validate
from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.dataset import DELAY_HALF_WIDTH, fault_draws, generate_dataset, skew_margin
from hybrid_sysid.data.spec import WindowSettings
from hybrid_sysid.physics import relative_states, road_profiles, seat_car, sensors, simulate
from hybrid_sysid.physics.sensors import SensorFaults

SMALL = dict(n_roads=3, n_masses=4, n_steps=300, seat_spread=0.2)
ALL = SensorFaults(gain_spread=0.03, skew_max=0.01, lowpass_range_hz=(20.0, 40.0))
# DatasetSpec().key() before the faults existed (commit d16e2a6): an old cache must stay valid
DEFAULT_KEY = "d0db5ab3c2dee04083b3"


@pytest.fixture(scope="module")
def pair():
    """(clean, faulted): one small dataset without and with every sensor fault."""
    return generate_dataset(DatasetSpec(**SMALL)), generate_dataset(DatasetSpec(**SMALL, sensor=ALL))


def clean_signals(spec: DatasetSpec, extra: int):
    """The clean float64 (seat, body) of every recording over n_steps + extra steps, by the numpy simulator, from
    the dataset's own draws (its generator, in generate_dataset's order)."""
    rng = np.random.default_rng(spec.seed)
    classes = spec.road_class(rng)
    masses = rng.integers(spec.m3_min, spec.m3_max + 1, size=(spec.n_roads, spec.n_masses)).astype(float)
    roads = road_profiles(classes, spec.n_steps + extra, spec.dt, spec.speed, spec.n_waves, rng)
    n, s = masses.size, spec.seat_spread
    c3, k3 = (value * rng.uniform(1 - s, 1 + s, size=n) for value in (spec.car.c3, spec.car.k3))
    car = seat_car(spec.car, n, c3, k3)
    return simulate(np.repeat(roads, spec.n_masses, axis=0), masses.ravel(), spec.dt, car, spec.measurement)


def test_no_fault_keeps_the_cache_key_and_the_data():
    assert DatasetSpec().key() == DEFAULT_KEY
    assert DatasetSpec(sensor=SensorFaults()).key() == DEFAULT_KEY
    keys = {DatasetSpec(sensor=f).key() for f in (SensorFaults(gain_spread=0.03), SensorFaults(skew_max=0.01), ALL)}
    assert len(keys) == 3 and DEFAULT_KEY not in keys


def test_faults_are_drawn_per_recording_reproducibly_and_leave_the_clean_draws(pair):
    clean, faulted = pair
    spec = faulted.spec
    first, again = fault_draws(spec), fault_draws(spec)
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)
    assert len(np.unique(first.gains[:, 0])) == len(faulted)  # one draw per recording
    for name in ("params", "m3", "c3", "k3", "road_id", "road_class"):  # the labels and the clean draws
        np.testing.assert_array_equal(getattr(faulted, name), getattr(clean, name))
    np.testing.assert_array_equal(generate_dataset(spec).body_acc, faulted.body_acc)
    other = fault_draws(DatasetSpec(**{**SMALL, "seed": 1}, sensor=ALL))
    assert not np.array_equal(other.gains, first.gains)


def test_the_dataset_is_the_numpy_path_on_the_clean_signals(pair):
    # the clean signals simulated past the end by the margin, rest before t0, sensors.apply, cropped, then
    # re-integrated: the kernel's float32 channels bit for bit
    _, faulted = pair
    spec = faulted.spec
    margin = skew_margin(spec)
    seat, body = (np.pad(x, ((0, 0), (margin, 0))) for x in clean_signals(spec, margin))
    seat, body = sensors.apply(seat, body, fault_draws(spec), spec.dt, DELAY_HALF_WIDTH)
    seat, body = seat[:, margin : margin + spec.n_steps], body[:, margin : margin + spec.n_steps]
    for name, want in zip(("seat_acc", "body_acc"), (seat, body)):
        np.testing.assert_allclose(getattr(faulted, name), want.astype(np.float32), rtol=0, atol=1e-7)
    rel = relative_states(seat, body, spec.dt, spec.measurement)
    for name, want in zip(("rel_vel", "rel_disp"), rel):
        scale = np.abs(want).max()
        np.testing.assert_allclose(getattr(faulted, name), want, rtol=0, atol=1e-6 * scale)


def test_rel_states_are_those_of_the_faulted_signals(pair):
    clean, faulted = pair
    spec = faulted.spec
    vel, disp = relative_states(faulted.seat_acc, faulted.body_acc, spec.dt, spec.measurement)
    for got, want in ((faulted.rel_vel, vel), (faulted.rel_disp, disp)):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-5 * np.abs(want).max())
    moved = np.abs(faulted.rel_vel - clean.rel_vel).max()
    assert moved > 1e-3 * np.abs(clean.rel_vel).max()  # and not the clean ones


def test_no_sample_reads_past_the_recording():
    # the skewed body channel against a reference with a far longer run-out on both sides: equal, so the margin
    # gives every sample, the last ones included, true samples to interpolate from
    spec = DatasetSpec(**SMALL, sensor=SensorFaults(skew_max=0.02))
    ds = generate_dataset(spec)
    long = 200
    seat, body = (np.pad(x, ((0, 0), (long, 0))) for x in clean_signals(spec, long))
    draws = fault_draws(spec)
    moved = sensors.fractional_delay(body, draws.skews / spec.dt, DELAY_HALF_WIDTH)[:, long : long + spec.n_steps]
    np.testing.assert_allclose(ds.body_acc, moved.astype(np.float32), rtol=0, atol=1e-7)


def test_gain_only_scales_the_clean_channels(pair):
    clean, _ = pair
    spec = DatasetSpec(**SMALL, sensor=SensorFaults(gain_spread=0.03))
    ds = generate_dataset(spec)
    gains = fault_draws(spec).gains
    np.testing.assert_allclose(ds.seat_acc, gains[:, :1] * clean.seat_acc, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(ds.body_acc, gains[:, 1:] * clean.body_acc, rtol=1e-6, atol=1e-9)


def test_continuous_recordings_take_faults_too():
    small = dict(n_roads=2, n_masses=2, n_steps=200, measurement="continuous")
    clean = generate_dataset(DatasetSpec(**small))
    spec = DatasetSpec(**small, sensor=SensorFaults(gain_spread=0.03))
    ds = generate_dataset(spec)
    gains = fault_draws(spec).gains
    np.testing.assert_allclose(ds.seat_acc, gains[:, :1] * clean.seat_acc, rtol=1e-6, atol=1e-9)


def test_a_skew_beyond_the_window_is_refused():
    spec = DatasetSpec(n_roads=4, n_masses=2, n_steps=300, sensor=SensorFaults(skew_max=1.0))
    spec.validate()  # the recording itself is fine
    with pytest.raises(ConfigError, match=r"^sensor.skew_max = 1.0 is not allowed: must be < data.window x data.dt"):
        WindowSettings(window=200).validate(spec)


@pytest.mark.parametrize(
    "overrides, match",
    [
        (["sensor.gain_spread=-0.1"], r"^sensor.gain_spread = -0.1 is not allowed: must lie in \[0, 1\)"),
        (["sensor.skew_max=1.0"], r"^sensor.skew_max = 1.0 is not allowed: .* beyond the window"),
        (["sensor.lowpass_hz=[20,120]"], r"^sensor.lowpass_hz = \[20.0, 120.0\] is not allowed: .*Nyquist"),
        (["sensor=lowpass", "sensor.lowpass_range_hz=[40,20]"], r"^sensor.lowpass_range_hz = .* lo <= hi"),
        (["car.seat_hardening=-1"], r"^car.seat_hardening = -1.0 is not allowed: must lie in \[0, "),
        (["car=hardening_seat", "data.measurement=continuous"], r"^car.seat_hardening = 35000.0 .* continuous"),
    ],
)
def test_bad_values_are_one_line_errors_naming_the_key(make_cfg, overrides, match):
    with pytest.raises(ConfigError, match=match) as info:
        validate(make_cfg("data=tiny", *overrides))
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "preset, faults, kappa",
    [
        ("sensor=none", SensorFaults(), 0.0),
        ("sensor=gain", SensorFaults(gain_spread=0.03), 0.0),
        ("sensor=skewed", SensorFaults(skew_max=0.01), 0.0),
        ("sensor=lowpass", SensorFaults(lowpass_range_hz=(20.0, 40.0)), 0.0),
        ("car=hardening_seat", SensorFaults(), 35000.0),
    ],
)
def test_the_presets_compose_and_validate(make_cfg, preset, faults, kappa):
    cfg = make_cfg("data=tiny", preset)
    validate(cfg)
    spec = DatasetSpec.from_config(cfg)
    assert spec.sensor == faults and spec.car.seat_hardening == kappa
    if preset == "sensor=none":
        assert spec.key() == DatasetSpec.from_config(make_cfg("data=tiny")).key()
