"""What a dataset is made of, without simulating it: ``DatasetSpec`` (every value that changes the simulated data,
the cache key) and ``WindowSettings`` (how the data module cuts the recordings). Plain Python and numpy, so the
config's checks run them without loading torch; the config's data section takes its keys from these two classes
(hybrid_sysid.config.schema), and ``DatasetSpec.from_config`` reads them back by field name.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from hybrid_sysid.core.checks import bad, check_choice, check_dt, check_int, check_number
from hybrid_sysid.core.options import DEFAULT_MEASUREMENT, INTEGRATIONS, MEASUREMENTS, ROAD_CLASSES, STEPPED
from hybrid_sysid.data.splits import Split, split_by_road
from hybrid_sysid.physics import QuarterCar, stable_dt_limit
from hybrid_sysid.physics.eiv.prior import check_seat_draws
from hybrid_sysid.physics.faults import SensorFaults, registered, settings
from hybrid_sysid.physics.road import OMEGA_M, check_classes, check_drive

# Bump whenever the simulator or the stored layout changes: old cache files are then never loaded.
SIMULATOR_VERSION = 4  # 2: relative states integrated from seat - body; 3: c3, k3 stored per recording;
# 4: every class on an equal share of the roads (the split per class), the continuous re-integration's gain corrected
CHANNELS = ("seat_acc", "body_acc", "rel_vel", "rel_disp")  # the channels a dataset holds for each recording
# DatasetSpec's fields that live outside the config's data section: road.classes, the car and sensor groups
OUTSIDE_DATA = {"road_classes", "car", "sensor"}
DT_RTOL = 1e-9  # a recording's dt counts as another's (a run's data.dt, a file's other recordings) within this
# the samples a band-pass must leave of each window (objective.filter, the least-squares baselines)
MIN_FILTERED = 10
SEED_MAX = 2**32 - 1  # numpy's and Lightning's seeds are 32-bit unsigned


def check_seed(key: str, value) -> int:
    """The one range of a seed (the run's ``seed``, ``data.seed``, ``tuned.seeds``): numpy's and Lightning's."""
    if isinstance(value, bool) or not (isinstance(value, int) and 0 <= value <= SEED_MAX):
        bad(key, value, f"must lie in [0, {SEED_MAX}] (a 32-bit unsigned seed)")
    return value


# a car's constant above this (kg, N/m, N s/m; a car's are 1e2 to 1e5) overflows the stability search's matrices
CAR_MAX = 1e9


@dataclass(frozen=True)
class DatasetSpec:
    """Every value that changes the simulated data (and nothing else): the cache key hashes all of it."""

    n_roads: int = 40
    n_masses: int = 50
    n_steps: int = 1200
    dt: float = 0.005
    speed: float = 15.0
    n_waves: int = 300
    road_classes: tuple = tuple(ROAD_CLASSES)
    m3_min: int = 50
    m3_max: int = 200
    measurement: str = DEFAULT_MEASUREMENT
    seed: int = 0
    car: QuarterCar = field(default_factory=QuarterCar)
    seat_spread: float = 0.0  # C3, K3 of each recording uniform in car.c3 * [1 - s, 1 + s], car.k3 * [1 - s, 1 + s]
    sensor: SensorFaults = field(default_factory=SensorFaults)  # the recording's sensor faults (docs/faults.md)

    def validate(self) -> None:
        """ConfigError naming the field (``car.<constant>`` for the car's), the value and what is allowed, before
        any work: the choices first, then each value once, then what depends on several of them, and last the
        stability search of the time step (the one check that costs)."""
        self.validate_values()
        self.validate_simulation()

    def validate_values(self) -> None:
        """``validate``'s checks of each value, without those of simulating (a user's recordings need only
        these: their step, measurement, car and prior range of p)."""
        check_choice("measurement", self.measurement, MEASUREMENTS)
        if not self.road_classes:  # a dataset splits its roads by class: none is not a dataset
            bad("road_classes", list(self.road_classes), f"a non-empty list of classes from {', '.join(ROAD_CLASSES)}")
        check_classes(self.road_classes)
        if not (isinstance(self.n_roads, int) and self.n_roads >= 2):
            bad("n_roads", self.n_roads, "need at least 2 roads to split by road into train and test")
        check_int("n_masses", self.n_masses, 1)
        check_int("n_steps", self.n_steps, 2)
        check_dt(self.dt)
        check_drive(self.speed, self.n_waves)
        check_seat_draws(self.m3_min, self.m3_max, self.seat_spread)
        check_seed("seed", self.seed)
        mismatches = settings("car")  # the car's faults (a hardening seat spring) check their own constants
        for name, value in asdict(self.car).items():
            if name not in mismatches and not (
                isinstance(value, (int, float)) and math.isfinite(value) and 0 < value <= CAR_MAX
            ):
                bad(f"car.{name}", value, f"must be finite and > 0, at most {CAR_MAX:g} (kg, N/m, N s/m)")
        for fault in registered("car"):
            fault.validate(self.car, self.dt, measurement=self.measurement)

    def validate_simulation(self) -> None:
        """``validate``'s checks of what only a simulation reads: the sensor faults, and the time step against
        the road's content (continuous) or the scheme's stability (stepped)."""
        self.sensor.validate(self.dt)
        if self.measurement not in STEPPED:  # exact samples of the continuous motion: the road is not sampled
            top = float(OMEGA_M) * self.speed / (2 * math.pi)  # the road's highest frequency at this speed, Hz
            if 0.5 / self.dt < top:
                bad(
                    "dt",
                    self.dt,
                    f"with measurement = continuous its Nyquist frequency, {0.5 / self.dt:.3g} Hz, lies below the "
                    f"road's content at speed = {self.speed:g} m/s (up to {top:.3g} Hz: wave numbers up to 6 pi "
                    f"rad/m), which would alias; allowed: dt <= {0.5 / top:.4g} s",
                )
        else:  # the continuous measurement takes no step
            limit = stable_dt_limit(self.car, self.m3_min, self.m3_max, self.seat_spread)
            if self.dt > limit:
                spread = f", seat_spread {self.seat_spread:g}" if self.seat_spread else ""
                bad(
                    "dt",
                    self.dt,
                    f"the semi-implicit Euler scheme is unstable above {limit:.4g} s for this car "
                    f"({self.car.describe()}; m3 in [{self.m3_min}, {self.m3_max}] kg{spread})",
                )

    def key(self) -> str:
        payload = asdict(self)
        payload["road_classes"] = list(self.road_classes)
        if not self.seat_spread:  # the paper's data keep their key
            payload.pop("seat_spread")
        for name, setting in settings("car").items():  # so do all data of a linear seat spring
            if payload["car"][name] == setting.default:
                payload["car"].pop(name)
        payload["sensor"] = self.sensor.key_values()  # and of ideal sensors (None: left out)
        if payload["sensor"] is None:
            payload.pop("sensor")
        payload["simulator_version"] = SIMULATOR_VERSION
        return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:20]

    def road_class(self, rng=None) -> np.ndarray:
        """The class letter of every road: each class of road.classes on an equal share of the roads (as near as
        n_roads allows), in random order, so that a split per class can put every class in every split. The
        dataset's first draw from its generator (``rng``, default a fresh one from data.seed), so a split knows
        the classes without simulating."""
        rng = np.random.default_rng(self.seed) if rng is None else rng
        return rng.permutation(np.resize(np.array(self.road_classes), self.n_roads))

    @classmethod
    def from_config(cls, cfg) -> "DatasetSpec":
        """The spec of a composed config: its data section's keys of the same names, road.classes, the car, the
        sensor faults."""
        d = cfg.data
        values = {f.name: d[f.name] for f in fields(cls) if f.name not in OUTSIDE_DATA and f.name in d}
        sensor = SensorFaults(**(cfg.get("sensor") or {}))
        car = QuarterCar(**cfg.get("car", {}))
        return cls(**values, road_classes=tuple(cfg.road.classes), car=car, sensor=sensor)


@dataclass(frozen=True)
class WindowSettings:
    """How the data module cuts the recordings into windows and splits them; none of it changes the data."""

    window: int = 500  # steps the network sees
    integration: str = "t0"  # how a window's sensor noise is re-integrated (hybrid_sysid.data.windows)
    train_fraction: float = 0.8  # of the roads; the rest are test roads
    val_fraction: float = 0.125  # of the training roads, held out for model selection

    def validate(
        self,
        spec: DatasetSpec,
        bounds: tuple[int, int | None] = (1, None),
        taps: int | None = None,
        outside_taps: int | None = None,
    ) -> None:
        """ConfigError naming the field; ``bounds``: the shortest and longest window the network reads (None: any),
        ``taps``: the length of a band-pass that each window must leave MIN_FILTERED samples of (the objective's),
        ``outside_taps``: that of the fit over the samples outside each window (``check_outside_fits``)."""
        check_choice("integration", self.integration, INTEGRATIONS)
        low, high = bounds
        top = spec.n_steps if high is None else min(high, spec.n_steps)
        if not (isinstance(self.window, int) and low <= self.window <= top):
            why = f" ({low} to {high or 'any number of'} steps: what the network reads)" if bounds != (1, None) else ""
            bad("window", self.window, f"must lie in [{low}, n_steps = {top}]{why}")
        spec.sensor.validate(spec.dt, self.window)  # a skew must stay within the window a network reads
        self.split(spec)
        check_filter_fits(taps, self.window, "taps", "window")
        check_outside_fits(outside_taps, spec.n_steps, self.window)

    @classmethod
    def from_config(cls, cfg) -> "WindowSettings":
        """The settings of a composed config: its data section's keys of the same names."""
        return cls(**{f.name: cfg.data[f.name] for f in fields(cls)})

    def split(self, spec: DatasetSpec) -> Split:
        """Train, validation and test recordings of the dataset: by road and per road class (data.splits)."""
        return split_by_road(spec.n_roads, spec.n_masses, self.train_fraction, self.val_fraction, spec.road_class())

    def n_starts(self, spec: DatasetSpec) -> int:
        """How many window starts a recording offers."""
        return starts_offered(spec.n_steps, self.window)


def starts_offered(n_steps, window):
    """How many window starts a recording of ``n_steps`` offers (an array of lengths: a count for each)."""
    return n_steps - window + 1


def window_starts(n_steps: int, window: int, k: int) -> np.ndarray:
    """K window starts evenly spaced over a recording of n_steps, the first at 0 and the last at the end (integer
    division: distinct whenever K <= n_steps - window + 1)."""
    return np.arange(k) * (n_steps - window) // max(k - 1, 1)


def check_filter_fits(taps: int | None, length: int, key: str, length_key: str) -> None:
    """A band-pass of ``taps`` must leave MIN_FILTERED samples of what it filters (a window or a recording), whose
    length ``length_key`` names."""
    if taps is not None and taps > length - MIN_FILTERED + 1:
        bad(
            key,
            taps,
            f"must be <= {length_key} - {MIN_FILTERED - 1} = {length - MIN_FILTERED + 1} (the band-pass must leave "
            f"at least {MIN_FILTERED} samples)",
        )


def outside_samples(n_steps: int, window: int, taps: int) -> int:
    """The fewest band-passed samples outside a window that any window start leaves: those whose whole FIR support
    lies before or after it, least for a window at least taps - 1 steps from either end."""
    return max(0, n_steps - window - 2 * (taps - 1))


def check_outside_fits(taps: int | None, n_steps: int, window: int) -> None:
    """A band-pass of ``taps`` over the rest of a recording (objective=cross_segment) must leave, outside every
    window, 2 (taps + MIN_FILTERED - 1) filtered samples: about two FIR lengths, so the fit spans more than the
    filter's own correlation of the noise."""
    if taps is None:
        return
    need = 2 * (taps + MIN_FILTERED - 1)
    if outside_samples(n_steps, window, taps) < need:
        bad(
            "n_steps",
            n_steps,
            f"must be >= data.window + 2 (objective.filter.taps - 1) + {need} = {window + 2 * (taps - 1) + need} "
            f"(window {window}, taps {taps}): the fit over the samples outside a window needs {need} band-passed "
            "samples; lengthen the recordings, shorten the window or the taps",
        )


def check_eval_windows(windows, n_starts: int, key: str = "windows") -> None:
    """K values, each an integer in [1, the window starts a recording offers] (evaluation.windows)."""
    windows = list(windows)
    if not windows or any(isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= n_starts for k in windows):
        bad(
            key,
            windows,
            f"a non-empty list of integers K in [1, data.n_steps - data.window + 1 = {n_starts}] (windows per "
            "recording)",
        )


# a noise std above this buries every road's accelerations (a few m/s^2) a thousand times over, and at 1e300 the
# noisy windows overflow float32: the loss is NaN at the first step
NOISE_MAX = 1000.0
NOISE_UNIT = "m/s^2, a road's accelerations are a few m/s^2"


@dataclass(frozen=True)
class BatchSettings:
    """How the data module serves training batches: their size and the Gaussian noise added to their windows."""

    batch_size: int = 64
    train_std: float = 0.0  # m/s^2, on both channels
    # m/s^2; set: each training window's std is log-uniform in [train_std, train_std_max] (None: train_std alone)
    train_std_max: float | None = None

    def validate(self) -> None:
        check_int("batch_size", self.batch_size, 1)
        check_number("train_std", self.train_std, 0, unit="m/s^2")
        check_number("train_std", self.train_std, high=NOISE_MAX, unit=NOISE_UNIT)
        if self.train_std_max is not None:
            if not self.train_std > 0:
                bad(
                    "train_std_max", self.train_std_max, "null unless train_std > 0 (the bottom of a log-uniform range)"
                )
            check_number("train_std_max", self.train_std_max, self.train_std, NOISE_MAX, low_open=True, unit=NOISE_UNIT)

    @property
    def val_std(self) -> float:
        """The noise std of the validation windows: train_std, or the geometric mean of the training range."""
        if self.train_std_max is None:
            return float(self.train_std)
        return math.sqrt(self.train_std * self.train_std_max)
