"""Dataset generation, splits and the cache."""

import dataclasses

import numpy as np
import pytest

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec, generate_dataset, get_dataset, split_by_road
from hybrid_sysid.data import cache as dataset_mod
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.physics import QuarterCar
from hybrid_sysid.physics.eiv import log_p_prior
from hybrid_sysid.physics.road import road_profiles
from hybrid_sysid.physics.sensors import SensorFaults

SMALL = DatasetSpec(n_roads=5, n_masses=4, n_steps=300, road_classes=("A", "C", "E"), seed=3)


@pytest.fixture(scope="module")
def small():
    return generate_dataset(SMALL)


def test_layout_labels_and_classes(small):
    n = 5 * 4
    assert small.seat_acc.shape == (n, 300) and small.seat_acc.dtype == np.float32
    for name in ("body_acc", "rel_vel", "rel_disp"):
        assert getattr(small, name).shape == (n, 300)
    assert np.all(small.m3 == np.round(small.m3)) and small.m3.min() >= 50 and small.m3.max() <= 200
    np.testing.assert_allclose(small.params[:, 0], 615.0 / small.m3)
    np.testing.assert_allclose(small.params[:, 1], 98935.0 / small.m3)
    assert set(small.road_class) <= {"A", "C", "E"}
    # road-major: each road's recordings are contiguous and share one class
    np.testing.assert_array_equal(small.road_id, np.repeat(np.arange(5), 4))
    for r in range(5):
        assert len(set(small.road_class[small.road_id == r])) == 1


def test_stored_states_give_back_p_by_least_squares(small):
    # float32 storage: the seat equation holds to float32 rounding, so p comes back far below 1e-3
    for i in range(len(small)):
        X = np.stack([-small.rel_vel[i], -small.rel_disp[i]], axis=1).astype(np.float64)
        p_hat = np.linalg.lstsq(X, small.seat_acc[i].astype(np.float64), rcond=None)[0]
        np.testing.assert_allclose(p_hat, small.params[i], rtol=1e-3)


def test_same_spec_same_data_other_seed_other_data(small):
    again = generate_dataset(SMALL)
    np.testing.assert_array_equal(again.seat_acc, small.seat_acc)
    other = generate_dataset(DatasetSpec(**{**SMALL.__dict__, "seed": 4}))
    assert not np.allclose(other.seat_acc, small.seat_acc)


def test_the_data_depend_on_data_seed_not_on_the_training_seed(make_cfg):
    spec = DatasetSpec.from_config(make_cfg())
    assert DatasetSpec.from_config(make_cfg("seed=7")) == spec  # every training seed sees the same data
    assert DatasetSpec.from_config(make_cfg("data.seed=7")) != spec


def test_split_by_road_never_shares_a_road():
    split = split_by_road(100, 100, 0.8, 0.125)
    road = lambda idx: set(idx // 100)  # noqa: E731
    assert road(split.test) == set(range(80, 100))
    assert road(split.val) == set(range(70, 80))
    assert road(split.train) == set(range(70))
    assert not road(split.train) & road(split.test) and not road(split.val) & road(split.test)


@pytest.mark.parametrize("data", ["default", "paper"])
def test_every_road_class_is_in_every_split(data):
    """data=default (40 roads) and data=paper (100 roads): the classes the simulator draws (its dataset's
    road_class array, not the spec's helper) are each in train, validation and test, no road is in two splits,
    and the sizes stay the position split's: 80% of the roads train or validate (the paper's 80 / 20)."""
    n_roads, n_masses = (40, 50) if data == "default" else (100, 100)
    spec = DatasetSpec(n_roads=n_roads, n_masses=n_masses, n_steps=20)  # the classes do not depend on the steps
    ds = generate_dataset(spec)
    split = QuarterCarDataModule(spec, window=10).split
    parts = {name: getattr(split, name) for name in ("train", "val", "test")}
    for name, rows in parts.items():
        assert set(ds.road_class[rows]) == set("ABCDE"), name
        assert len(rows) % n_masses == 0 and set(np.bincount(ds.road_id[rows])) <= {0, n_masses}  # whole roads
    roads = {name: set(ds.road_id[rows]) for name, rows in parts.items()}
    assert not roads["train"] & roads["val"] and not roads["train"] & roads["test"] and not roads["val"] & roads["test"]
    assert len(roads["train"] | roads["val"]) == round(0.8 * n_roads)
    assert sorted(roads["train"] | roads["val"] | roads["test"]) == list(range(n_roads))
    counts = np.unique(ds.road_class[::n_masses], return_counts=True)[1]
    assert counts.max() - counts.min() <= 1  # every class on an equal share of the roads


def test_a_class_too_small_for_every_split_falls_back_to_the_split_by_position():
    """Six roads of five classes: one class has two roads, the others one, so no split can hold every class."""
    classes = np.array(list("ABCDEA"))
    by_class, by_position = split_by_road(6, 2, 0.8, 0.25, classes), split_by_road(6, 2, 0.8, 0.25)
    for name in ("train", "val", "test"):
        np.testing.assert_array_equal(getattr(by_class, name), getattr(by_position, name))
    assert set(by_position.test // 2) == {5}  # the last road tests


def test_cache_loads_instead_of_simulating(tmp_path, monkeypatch, small):
    first = get_dataset(SMALL, tmp_path)
    files = list(tmp_path.glob("qcm-*.npz"))
    assert len(files) == 1

    def boom(spec):
        raise AssertionError("simulated again instead of loading the cache")

    monkeypatch.setattr(dataset_mod, "generate_dataset", boom)
    second = get_dataset(SMALL, tmp_path)
    for name in ("seat_acc", "body_acc", "rel_vel", "rel_disp", "params", "m3", "road_id", "road_class"):
        np.testing.assert_array_equal(getattr(second, name), getattr(first, name))


# one changed value for every field of DatasetSpec, each car constant and each sensor fault
CHANGES = {
    "n_roads": 6,
    "n_masses": 5,
    "n_steps": 301,
    "dt": 0.004,
    "speed": 12.0,
    "n_waves": 200,
    "road_classes": ("B",),
    "m3_min": 60,
    "m3_max": 190,
    "measurement": "paper",
    "seed": 9,
    "seat_spread": 0.1,
    **{f"car.{name}": value * 1.1 + 0.01 for name, value in dataclasses.asdict(QuarterCar()).items()},
    "sensor.gain_spread": 0.05,
    "sensor.skew_max": 0.01,
    "sensor.lowpass_hz": 10.0,
    "sensor.lowpass_range_hz": [5.0, 20.0],
}


def test_cache_key_changes_with_every_value_that_changes_the_data():
    nested = {"car": QuarterCar, "sensor": SensorFaults}
    every = [f.name for f in dataclasses.fields(DatasetSpec) if f.name not in nested]
    every += [f"car.{f.name}" for f in dataclasses.fields(QuarterCar)]
    every += [f"sensor.{name}" for name in SensorFaults().values()]  # every registered sensor fault's settings
    assert sorted(CHANGES) == sorted(every)  # a new field gets its line here
    for name, value in CHANGES.items():
        group, _, key = name.rpartition(".")
        if group == "car":  # a constant of the car
            value = dataclasses.replace(SMALL.car, **{key: value})
        elif group:  # a fault of the sensors
            value = SMALL.sensor.replace(**{key: value})
        changed = dataclasses.replace(SMALL, **{group or key: value})
        assert changed != SMALL and changed.key() != SMALL.key(), name


def test_interrupted_write_leaves_nothing_loadable(tmp_path, monkeypatch):
    def crash(fh, **arrays):
        fh.write(b"half a file")
        raise KeyboardInterrupt

    monkeypatch.setattr(dataset_mod.np, "savez", crash)
    with pytest.raises(KeyboardInterrupt):
        get_dataset(SMALL, tmp_path)
    assert [p for p in tmp_path.iterdir() if p.suffix != ".lock"] == []


def test_a_changed_simulator_never_loads_an_old_file(tmp_path, monkeypatch, small):
    from hybrid_sysid.data import spec as spec_mod

    get_dataset(SMALL, tmp_path)  # the file of the simulator as it is
    (old,) = tmp_path.glob("qcm-*.npz")
    monkeypatch.setattr(spec_mod, "SIMULATOR_VERSION", spec_mod.SIMULATOR_VERSION + 1)
    newer = dataclasses.replace(small, seat_acc=small.seat_acc + 1.0)  # what the changed simulator gives
    simulated = []
    monkeypatch.setattr(dataset_mod, "generate_dataset", lambda spec: simulated.append(spec) or newer)
    again = get_dataset(SMALL, tmp_path)
    assert simulated == [SMALL]
    np.testing.assert_array_equal(again.seat_acc, newer.seat_acc)
    # the old file, even under the new key's name, holds its own key: refused, regenerated, never loaded
    (new,) = set(tmp_path.glob("qcm-*.npz")) - {old}
    new.write_bytes(old.read_bytes())
    with pytest.warns(RuntimeWarning, match="another dataset"):
        again = get_dataset(SMALL, tmp_path)
    assert len(simulated) == 2
    np.testing.assert_array_equal(again.seat_acc, newer.seat_acc)


@pytest.mark.parametrize("damage", ["truncate", "flip", "garbage"])
def test_damaged_cache_is_regenerated_with_a_warning(tmp_path, small, damage):
    get_dataset(SMALL, tmp_path)
    (path,) = tmp_path.glob("qcm-*.npz")
    raw = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(raw[: len(raw) // 2])
    elif damage == "flip":  # one byte inside the seat channel's data: still a valid npz
        with np.load(path) as f:
            names = f.files
        assert "seat_acc" in names
        i = raw.index(small.seat_acc[3].tobytes()[:64])
        path.write_bytes(raw[:i] + bytes([raw[i] ^ 0xFF]) + raw[i + 1 :])
    else:
        path.write_bytes(b"not a cache file")
    with pytest.warns(RuntimeWarning, match="regenerating"):
        again = get_dataset(SMALL, tmp_path)
    np.testing.assert_array_equal(again.seat_acc, small.seat_acc)
    reloaded = get_dataset(SMALL, tmp_path)  # the regenerated file is whole again
    np.testing.assert_array_equal(reloaded.seat_acc, small.seat_acc)


def test_a_fifo_or_a_device_in_the_cache_files_place_is_regenerated_not_waited_on(tmp_path, small):
    """A FIFO named as the cache file blocked the run (and the cache's lock) for ever, deaf to SIGTERM: the file
    is no regular file, so it is regenerated with a warning, as a damaged one is."""
    import os
    import threading

    path = dataset_mod.cache_path(SMALL, tmp_path)
    os.mkfifo(path)
    got = {}

    def load():
        with pytest.warns(RuntimeWarning, match="no regular file; regenerating"):
            got["ds"] = get_dataset(SMALL, tmp_path)

    reader = threading.Thread(target=load, daemon=True)
    reader.start()
    reader.join(120)  # far beyond the simulation of SMALL; without the check it waits for a writer for ever
    if reader.is_alive():  # a writer opens and closes the FIFO, so the reader ends
        os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
        reader.join(10)
    assert "ds" in got and path.is_file()
    np.testing.assert_array_equal(got["ds"].seat_acc, small.seat_acc)
    path.unlink()
    path.symlink_to("/dev/zero")
    with pytest.warns(RuntimeWarning, match="no regular file; regenerating"):
        np.testing.assert_array_equal(get_dataset(SMALL, tmp_path).seat_acc, small.seat_acc)


GENERATE_ONCE = """
import sys, time
from hybrid_sysid.data import cache as d
real = d.generate_dataset
def counted(spec):
    with open(sys.argv[2], "a") as fh:
        fh.write("generated\\n")
    time.sleep(1.0)  # hold the lock long enough for the other process to arrive
    return real(spec)
d.generate_dataset = counted
ds = d.get_dataset(d.DatasetSpec(n_roads=3, n_masses=2, n_steps=200, seed=5), sys.argv[1])
print(float(ds.seat_acc.sum()))
"""


@pytest.mark.integration
def test_concurrent_jobs_generate_a_dataset_once(tmp_path):
    # real processes: two at once, sharing an empty cache through its file lock
    import subprocess
    import sys

    counter = tmp_path / "count.txt"
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", GENERATE_ONCE, str(tmp_path / "cache"), str(counter)],
            stdout=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=300)[0] for p in procs]
    assert [p.returncode for p in procs] == [0, 0]
    assert counter.read_text().splitlines() == ["generated"]
    assert outs[0] == outs[1]


BAD = [
    (dict(road_classes=("A", "Z")), r"road_classes = \['A', 'Z'\] is not allowed: each class must be one of A, B"),
    (dict(dt=0.0), r"dt = 0.0 is not allowed: must be > 0"),
    (dict(dt=0.5), r"dt = 0.5 is not allowed: the semi-implicit Euler scheme is unstable above 0.03"),
    (dict(speed=-3.0), r"speed = -3.0 is not allowed: must be > 0"),
    (dict(m3_min=120, m3_max=80), r"m3_max = 80 is not allowed: empty mass range"),
    (dict(m3_min=-5), r"m3_min = -5 is not allowed: must be an integer >= 1"),
    (dict(n_roads=1), r"n_roads = 1 is not allowed: need at least 2 roads"),
    (dict(measurement="exact"), r"measurement = 'exact' is not allowed: one of paper, consistent"),
]


@pytest.mark.parametrize("change, match", BAD)
def test_bad_values_fail_before_anything_is_written(tmp_path, change, match):
    with pytest.raises(ValueError, match=match):
        get_dataset(DatasetSpec(**{**SMALL.__dict__, **change}), tmp_path)
    assert list(tmp_path.iterdir()) == []  # not even a lock file


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(window=301), r"window = 301 is not allowed: must lie in \[1, n_steps = 300\]"),
        (dict(train_fraction=1.0), r"train_fraction = 1.0 is not allowed: must lie in \(0, 1\)"),
        (dict(train_fraction=0.2), r"n_roads = 5 is not allowed: too few for train_fraction = 0.2"),
        (dict(train_std=-0.01), r"train_std = -0.01 is not allowed"),
        (dict(batch_size=0), r"batch_size = 0 is not allowed"),
    ],
)
def test_bad_datamodule_values_fail_before_anything_is_written(tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        QuarterCarDataModule(SMALL, cache_dir=str(tmp_path), **({"window": 100} | kwargs))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("speed", [5.0, 15.0, 30.0])
def test_continuous_recordings_refuse_a_dt_that_aliases_the_road(speed):
    """The road's highest wave number is 6 pi rad/m (sec. 2.1), so at speed v its content reaches 3 v Hz: a
    continuous recording needs 1 / (2 dt) >= 3 v."""
    limit = 1 / (6 * speed)
    DatasetSpec(measurement="continuous", speed=speed, dt=limit * 0.99, n_steps=10).validate()
    with pytest.raises(ValueError, match=rf"^dt = .* is not allowed: .*up to {3 * speed:.3g} Hz"):
        DatasetSpec(measurement="continuous", speed=speed, dt=limit * 1.01, n_steps=10).validate()
    DatasetSpec(measurement="consistent", speed=speed, dt=min(limit * 1.01, 0.03), n_steps=10).validate()


def test_a_cache_directory_that_cannot_be_searched_costs_a_warning(tmp_path, monkeypatch, small):
    """A cache directory of mode 000 (root ignores modes, so the test makes its stat fail the same way): the run
    goes on with the simulated dataset and a warning, as the docs promise for a cache that cannot be written."""
    import pathlib

    real_exists, real_mkdir = pathlib.Path.exists, pathlib.Path.mkdir

    def exists(self, *args, **kwargs):
        if self.parent == tmp_path / "locked":
            raise PermissionError(13, "Permission denied", str(self))
        return real_exists(self, *args, **kwargs)

    def mkdir(self, *args, **kwargs):
        if self.parent == tmp_path / "locked":
            raise PermissionError(13, "Permission denied", str(self))
        return real_mkdir(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "exists", exists)
    monkeypatch.setattr(pathlib.Path, "mkdir", mkdir)
    (tmp_path / "locked").mkdir()
    with pytest.warns(RuntimeWarning, match="cannot be read"):
        ds = get_dataset(SMALL, tmp_path / "locked")
    np.testing.assert_array_equal(ds.seat_acc, small.seat_acc)


@pytest.mark.parametrize(
    "spec_kwargs, physics_call",
    [
        (dict(road_classes=("A", "F")), lambda: road_profiles(["A", "F"], 10, 0.005, 15.0)),
        (dict(speed=-2.0), lambda: road_profiles(["A"], 10, 0.005, -2.0)),
        (dict(n_waves=1), lambda: road_profiles(["A"], 10, 0.005, 15.0, n_waves=1)),
        (dict(m3_min=0), lambda: log_p_prior(0, 200, 1.0, 1.0, 0.0)),
        (dict(m3_min=120, m3_max=80), lambda: log_p_prior(120, 80, 1.0, 1.0, 0.0)),
        (dict(seat_spread=1.0), lambda: log_p_prior(50, 200, 1.0, 1.0, 1.0)),
    ],
)
def test_the_spec_and_the_physics_refuse_a_range_in_the_same_words(spec_kwargs, physics_call):
    """Each range has one owner in physics (the road's, the seat draws'), which the dataset's spec calls: a
    copy would drift, as the road classes' words once did."""
    with pytest.raises(ConfigError) as from_spec:
        DatasetSpec(**spec_kwargs).validate()
    with pytest.raises(ConfigError) as from_physics:
        physics_call()
    assert str(from_spec.value) == str(from_physics.value)
