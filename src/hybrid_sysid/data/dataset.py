"""Dataset generation (sec. 2.3) and its on-disk cache.

Recordings are stored road-major (recording = road * n_masses + mass index), so a split by road is a
contiguous range of recordings and no test road is ever seen in training.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from filelock import FileLock

from hybrid_sysid.files import write_atomic
from hybrid_sysid.physics import (DEFAULT_MEASUREMENT, MEASUREMENTS, ROAD_CLASSES, STEPPED, QuarterCar,
                                  continuous_recordings, relative_states, road_amplitudes, road_phases,
                                  road_profiles, stable_dt_limit, wave_numbers)
from hybrid_sysid.physics.compiled import simulate_recordings

log = logging.getLogger(__name__)

# Bump whenever the simulator or the stored layout changes: old cache files are then never loaded.
SIMULATOR_VERSION = 3  # 2: relative states integrated from seat - body; 3: c3, k3 stored per recording
CHANNELS = ("seat_acc", "body_acc", "rel_vel", "rel_disp")
# data.integration: how the data module re-integrates a window's sensor noise (QCMData); here, beside the
# dataset, so the config checks it without loading torch
INTEGRATIONS = ("t0", "window")


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
        """Raise ValueError naming the key, the value and what is allowed; called before any work."""
        def bad(key, value, allowed):
            raise ValueError(f"{key} = {value!r} is not allowed: {allowed}")

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
                bad(f"{prefix}.dt", self.dt, f"the semi-implicit Euler scheme is unstable above {limit:.4g} s for "
                    f"this car ({self.car.describe()}; m3 in [{self.m3_min}, {self.m3_max}] kg{spread})")
        if not self.speed > 0:
            bad(f"{prefix}.speed", self.speed, "must be > 0 (m/s)")
        if self.n_waves < 2:
            bad(f"{prefix}.n_waves", self.n_waves, "must be >= 2")
        if self.amplitude not in ("paper", "iso"):
            bad(f"{prefix}.amplitude", self.amplitude, "one of paper, iso")
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


@dataclass
class QCMDataset:
    """Arrays of one simulated dataset. Channels are float32 (n_recordings, n_steps); labels float64."""

    spec: DatasetSpec
    seat_acc: np.ndarray
    body_acc: np.ndarray
    rel_vel: np.ndarray
    rel_disp: np.ndarray
    params: np.ndarray  # (n, 2): p1 = C3 / m3, p2 = K3 / m3
    m3: np.ndarray  # (n,)
    c3: np.ndarray  # (n,) the seat's damping and stiffness of each recording (the car's unless data.seat_spread)
    k3: np.ndarray  # (n,)
    road_id: np.ndarray  # (n,)
    road_class: np.ndarray  # (n,) class letters

    def __len__(self) -> int:
        return self.seat_acc.shape[0]

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, n).nbytes for n in _ARRAYS)


def generate_dataset(spec: DatasetSpec) -> QCMDataset:
    """Simulate every mass on every road.

    The compiled kernel (physics.compiled) steps the simulation in float64 and writes the float32 channels
    directly: the same numbers as ``simulate`` and ``relative_states`` cast to float32.
    """
    spec.validate()
    rng = np.random.default_rng(spec.seed)
    classes = rng.choice(list(spec.road_classes), size=spec.n_roads)
    masses = rng.integers(spec.m3_min, spec.m3_max + 1, size=(spec.n_roads, spec.n_masses)).astype(float).ravel()
    road_id = np.repeat(np.arange(spec.n_roads), spec.n_masses)
    if spec.measurement in STEPPED:
        roads = road_profiles(classes, spec.n_steps, spec.dt, spec.speed, spec.n_waves, spec.amplitude, rng)
    else:  # the same draw of phases; the road stays analytic
        phases = road_phases(spec.n_roads, spec.n_waves, rng)
    c3, k3 = np.full(len(masses), spec.car.c3), np.full(len(masses), spec.car.k3)
    if spec.seat_spread:  # drawn after the roads, so a spread of 0 leaves the paper's data as they were
        s = spec.seat_spread
        c3 = spec.car.c3 * rng.uniform(1 - s, 1 + s, size=len(masses))
        k3 = spec.car.k3 * rng.uniform(1 - s, 1 + s, size=len(masses))

    # float64 physics ends here: the network and the objectives work in float32
    if spec.measurement in STEPPED:
        channels = simulate_recordings(roads, road_id, masses, spec.dt, spec.car, spec.measurement, c3=c3, k3=k3)
    else:
        seat, body = continuous_recordings(road_amplitudes(classes, spec.n_waves, spec.amplitude), phases,
                                           wave_numbers(spec.n_waves) * spec.speed, road_id, masses, spec.n_steps,
                                           spec.dt, spec.car, c3=c3, k3=k3)
        rel = relative_states(seat, body, spec.dt, spec.measurement)
        channels = tuple(x.astype(np.float32) for x in (seat, body, *rel))
    return QCMDataset(
        spec=spec,
        params=np.stack([c3 / masses, k3 / masses], axis=1),
        m3=masses,
        c3=c3,
        k3=k3,
        road_id=road_id,
        road_class=np.repeat(classes, spec.n_masses),
        **dict(zip(CHANNELS, channels)),
    )


def cache_path(spec: DatasetSpec, cache_dir: str | os.PathLike) -> Path:
    return Path(cache_dir).expanduser() / f"qcm-{spec.key()}.npz"


_ARRAYS = CHANNELS + ("params", "m3", "c3", "k3", "road_id", "road_class")


def _checksum(arrays: dict) -> str:
    """sha256 over every stored array's bytes, in a fixed order: a truncated or altered file never matches."""
    h = hashlib.sha256()
    for name in _ARRAYS:
        h.update(name.encode())
        h.update(np.ascontiguousarray(arrays[name]).tobytes())
    return h.hexdigest()


def save_dataset(ds: QCMDataset, path: Path) -> None:
    """Write atomically (files.write_atomic), so a crash leaves nothing loadable."""
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {name: getattr(ds, name) for name in _ARRAYS}
    arrays["road_class"] = arrays["road_class"].astype("U1")
    checksum = _checksum(arrays)

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, key=np.array(ds.spec.key()), checksum=np.array(checksum), **arrays)

    write_atomic(path, write)


class CacheError(ValueError):
    """A cache file that cannot be trusted: unreadable, truncated, altered, or another dataset's."""


def load_dataset(spec: DatasetSpec, path: Path) -> QCMDataset:
    try:
        with np.load(path, allow_pickle=False) as f:
            key, checksum = str(f["key"]), str(f["checksum"])
            arrays = {name: f[name] for name in _ARRAYS}
    except Exception as exc:  # zipfile, OSError, KeyError, ValueError: all mean "do not trust this file"
        raise CacheError(f"cache file {path} is unreadable ({type(exc).__name__}: {exc})") from exc
    if key != spec.key():
        raise CacheError(f"cache file {path} holds another dataset (key {key}, expected {spec.key()})")
    if _checksum(arrays) != checksum:
        raise CacheError(f"cache file {path} fails its checksum (altered or corrupted)")
    return QCMDataset(spec=spec, **arrays)


def _cache_warning(message: str) -> None:
    warnings.warn(message, RuntimeWarning, stacklevel=3)
    log.warning(message)


def _remove_stale_temporaries(path: Path) -> None:
    """Temporary files of ``path`` left by a writer that was killed (files.write_atomic names them
    .<name>.<random>.tmp). Called under the file's lock: only the lock's holder writes them, so none is live."""
    for tmp in path.parent.glob(f".{path.name}.*.tmp"):
        try:
            tmp.unlink()
            log.info("removed %s, left by an interrupted write", tmp)
        except OSError:
            pass


def get_dataset(spec: DatasetSpec, cache_dir: str | os.PathLike | None = None) -> QCMDataset:
    """Load the dataset from the cache if present and intact, otherwise simulate it and store it.

    A file lock makes concurrent jobs (a sweep) generate a dataset once: the others wait, then load it.
    A cache file that fails its checks is regenerated, with a warning, never loaded. A cache that cannot be
    written (read-only, full, a directory in the file's place) costs a warning: the dataset is then simulated
    and used from memory, and a valid file in a read-only cache is still read.
    """
    spec.validate()
    if cache_dir is None:
        return generate_dataset(spec)
    path = cache_path(spec, cache_dir)
    lock = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = FileLock(str(path) + ".lock", timeout=-1)
        lock.acquire()
    except OSError as exc:
        lock = None
        _cache_warning(f"dataset cache {path.parent} cannot be locked ({type(exc).__name__}: {exc}); "
                       "using it without the lock")
    try:
        if lock is not None:
            _remove_stale_temporaries(path)
        if path.exists():
            try:
                ds = load_dataset(spec, path)
                log.info("loaded cached dataset %s", path)
                return ds
            except CacheError as exc:
                _cache_warning(f"{exc}; regenerating it")
        log.info("simulating %d roads x %d masses x %d steps -> %s", spec.n_roads, spec.n_masses, spec.n_steps,
                 path)
        ds = generate_dataset(spec)
        try:
            save_dataset(ds, path)
        except OSError as exc:
            _cache_warning(f"dataset not cached at {path} ({type(exc).__name__}: {exc}); using it from memory")
        return ds
    finally:
        if lock is not None:
            lock.release()
