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

from hybrid_sysid.core.checks import ConfigError, check_choice
from hybrid_sysid.core.options import AMPLITUDES, INTEGRATIONS
from hybrid_sysid.data.splits import Split, split_by_road
from hybrid_sysid.physics import DEFAULT_MEASUREMENT, MEASUREMENTS, ROAD_CLASSES, STEPPED, QuarterCar, stable_dt_limit
from hybrid_sysid.physics.road import OMEGA_M

# Bump whenever the simulator or the stored layout changes: old cache files are then never loaded.
SIMULATOR_VERSION = 4  # 2: relative states integrated from seat - body; 3: c3, k3 stored per recording;
# 4: every class on an equal share of the roads (the split per class), the continuous re-integration's gain corrected
# DatasetSpec's fields that live outside the config's data section: road.classes and the car group
OUTSIDE_DATA = {"road_classes", "car"}
# the samples a band-pass must leave of each window (objective.filter, the least-squares baselines)
MIN_FILTERED = 10


@dataclass(frozen=True)
class DatasetSpec:
    """Every value that changes the simulated data (and nothing else): the cache key hashes all of it."""

    n_roads: int = 40
    n_masses: int = 50
    n_steps: int = 1200
    dt: float = 0.005
    speed: float = 15.0
    n_waves: int = 300
    amplitude: str = "paper"
    road_classes: tuple = tuple(ROAD_CLASSES)
    m3_min: int = 50
    m3_max: int = 200
    measurement: str = DEFAULT_MEASUREMENT
    seed: int = 0
    car: QuarterCar = field(default_factory=QuarterCar)
    seat_spread: float = 0.0  # C3, K3 of each recording uniform in car.c3 * [1 - s, 1 + s], car.k3 * [1 - s, 1 + s]

    def validate(self, prefix: str = "data") -> None:
        """Raise ConfigError (a ValueError) naming the key, the value and what is allowed; before any work."""

        def bad(key, value, allowed):
            raise ConfigError(f"{key} = {value!r} is not allowed: {allowed}")

        if self.n_roads < 2:
            bad(f"{prefix}.n_roads", self.n_roads, "need at least 2 roads to split by road into train and test")
        if self.n_masses < 1:
            bad(f"{prefix}.n_masses", self.n_masses, "must be >= 1")
        if self.n_steps < 2:
            bad(f"{prefix}.n_steps", self.n_steps, "must be >= 2")
        if not self.dt > 0:
            bad(f"{prefix}.dt", self.dt, "must be > 0 (seconds)")
        if not 0 <= self.seat_spread < 1:
            bad(f"{prefix}.seat_spread", self.seat_spread, "must lie in [0, 1) (a fraction of car.c3 and car.k3)")
        if self.measurement in STEPPED and self.m3_min > 0:  # the continuous measurement takes no step
            limit = stable_dt_limit(self.car, self.m3_min, self.m3_max, self.seat_spread)
            if self.dt > limit:
                spread = f", seat_spread {self.seat_spread:g}" if self.seat_spread else ""
                bad(
                    f"{prefix}.dt",
                    self.dt,
                    f"the semi-implicit Euler scheme is unstable above {limit:.4g} s for "
                    f"this car ({self.car.describe()}; m3 in [{self.m3_min}, {self.m3_max}] kg{spread})",
                )
        if not self.speed > 0:
            bad(f"{prefix}.speed", self.speed, "must be > 0 (m/s)")
        if self.measurement not in STEPPED:  # exact samples of the continuous motion: the road is not sampled
            top = float(OMEGA_M) * self.speed / (2 * math.pi)  # the road's highest frequency at this speed, Hz
            if 0.5 / self.dt < top:
                bad(
                    f"{prefix}.dt",
                    self.dt,
                    f"with {prefix}.measurement = continuous its Nyquist frequency, {0.5 / self.dt:.3g} Hz, lies "
                    f"below the road's content at {prefix}.speed = {self.speed:g} m/s (up to {top:.3g} Hz: wave "
                    f"numbers up to 6 pi rad/m), which would alias; allowed: dt <= {0.5 / top:.4g} s",
                )
        if not self.speed > 0:
            bad(f"{prefix}.speed", self.speed, "must be > 0 (m/s)")
        if self.n_waves < 2:
            bad(f"{prefix}.n_waves", self.n_waves, "must be >= 2")
        if self.amplitude not in AMPLITUDES:
            bad(f"{prefix}.amplitude", self.amplitude, f"one of {', '.join(AMPLITUDES)}")
        if not self.road_classes:
            bad("road.classes", list(self.road_classes), f"a non-empty list of classes from {', '.join(ROAD_CLASSES)}")
        for c in self.road_classes:
            if c not in ROAD_CLASSES:
                bad("road.classes", list(self.road_classes), f"each class must be one of {', '.join(ROAD_CLASSES)}")
        if self.m3_min <= 0:
            bad(f"{prefix}.m3_min", self.m3_min, "must be > 0 kg")
        if self.m3_max < self.m3_min:
            bad(f"{prefix}.m3_max", self.m3_max, f"empty mass range: must be >= data.m3_min = {self.m3_min}")
        if self.measurement not in MEASUREMENTS:
            bad(f"{prefix}.measurement", self.measurement, f"one of {', '.join(MEASUREMENTS)}")

    def key(self) -> str:
        payload = asdict(self)
        payload["road_classes"] = list(self.road_classes)
        if not self.seat_spread:  # the paper's data keep their key
            payload.pop("seat_spread")
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
        """The spec of a composed config: its data section's keys of the same names, road.classes, the car."""
        d = cfg.data
        values = {f.name: d[f.name] for f in fields(cls) if f.name not in OUTSIDE_DATA and f.name in d}
        return cls(**values, road_classes=tuple(cfg.road.classes), car=QuarterCar(**cfg.get("car", {})))


@dataclass(frozen=True)
class WindowSettings:
    """How the data module cuts the recordings into windows and splits them; none of it changes the data."""

    window: int = 500  # steps the network sees
    integration: str = "t0"  # how a window's sensor noise is re-integrated (hybrid_sysid.data.windows)
    train_fraction: float = 0.8  # of the roads; the rest are test roads
    val_fraction: float = 0.125  # of the training roads, held out for model selection

    def validate(self, spec: DatasetSpec, min_window: int = 1, taps: int | None = None) -> None:
        """Raise ConfigError naming the key; ``min_window``: the network's shortest window, ``taps``: a band-pass
        that each window must leave MIN_FILTERED samples of."""
        if not min_window <= self.window <= spec.n_steps:
            why = f" ({min_window} = the shortest window the network's kernels fit)" if min_window > 1 else ""
            raise ConfigError(
                f"data.window = {self.window} is not allowed: must lie in [{min_window}, "
                f"data.n_steps = {spec.n_steps}]{why}"
            )
        check_choice("data.integration", self.integration, INTEGRATIONS)
        self.split(spec)
        check_filter_fits(taps, self.window, "objective.filter.taps", "data.window")

    def split(self, spec: DatasetSpec) -> Split:
        """Train, validation and test recordings of the dataset: by road and per road class (data.splits)."""
        return split_by_road(spec.n_roads, spec.n_masses, self.train_fraction, self.val_fraction, spec.road_class())

    def n_starts(self, spec: DatasetSpec) -> int:
        """How many window starts a recording offers."""
        return spec.n_steps - self.window + 1


def check_filter_fits(taps: int | None, length: int, key: str, length_key: str) -> None:
    """A band-pass of ``taps`` must leave MIN_FILTERED samples of what it filters (a window or a recording)."""
    if taps is not None and taps > length - MIN_FILTERED + 1:
        raise ConfigError(
            f"{key} = {taps} is not allowed: must be <= {length_key} - {MIN_FILTERED - 1} = "
            f"{length - MIN_FILTERED + 1} (the band-pass must leave at least {MIN_FILTERED} samples)"
        )


def check_eval_windows(windows, n_starts: int) -> None:
    """evaluation.windows: K values, each an integer in [1, the window starts a recording offers]."""
    windows = list(windows)
    if not windows or any(isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= n_starts for k in windows):
        raise ConfigError(
            f"evaluation.windows = {windows} is not allowed: a non-empty list of integers K in [1, "
            f"data.n_steps - data.window + 1 = {n_starts}] (windows per recording)"
        )
