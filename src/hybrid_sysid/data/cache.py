"""The dataset cache: one checksummed .npz file per DatasetSpec key, written atomically under a file lock."""

from __future__ import annotations

import hashlib
import logging
import os
import warnings
from pathlib import Path

import numpy as np
from filelock import FileLock, Timeout

from hybrid_sysid.core import stop
from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.data.dataset import ARRAYS, SimulatedDataset, generate_dataset
from hybrid_sysid.data.spec import DatasetSpec

log = logging.getLogger(__name__)


def cache_path(spec: DatasetSpec, cache_dir: str | os.PathLike) -> Path:
    return Path(cache_dir).expanduser() / f"qcm-{spec.key()}.npz"


def _checksum(arrays: dict) -> str:
    """sha256 over every stored array's bytes, in a fixed order: a truncated or altered file never matches."""
    h = hashlib.sha256()
    for name in ARRAYS:
        h.update(name.encode())
        h.update(np.ascontiguousarray(arrays[name]).tobytes())
    return h.hexdigest()


def save_dataset(ds: SimulatedDataset, path: Path) -> None:
    """Write atomically (files.write_atomic), so a crash leaves nothing loadable."""
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {name: getattr(ds, name) for name in ARRAYS}
    arrays["road_class"] = arrays["road_class"].astype("U1")
    checksum = _checksum(arrays)

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, key=np.array(ds.spec.key()), checksum=np.array(checksum), **arrays)

    write_atomic(path, write)


class CacheError(ValueError):
    """A cache file that cannot be trusted: unreadable, truncated, altered, or another dataset's."""


def load_dataset(spec: DatasetSpec, path: Path) -> SimulatedDataset:
    if not Path(path).is_file():  # a FIFO would block np.load for ever, deaf to SIGTERM; a device reads on
        raise CacheError(f"cache file {path} is no regular file")
    try:
        with np.load(path, allow_pickle=False) as f:
            key, checksum = str(f["key"]), str(f["checksum"])
            arrays = {name: f[name] for name in ARRAYS}
    except Exception as exc:  # zipfile, OSError, KeyError, ValueError: all mean "do not trust this file"
        raise CacheError(f"cache file {path} is unreadable ({type(exc).__name__}: {exc})") from exc
    if key != spec.key():
        raise CacheError(f"cache file {path} holds another dataset (key {key}, expected {spec.key()})")
    if _checksum(arrays) != checksum:
        raise CacheError(f"cache file {path} fails its checksum (altered or corrupted)")
    return SimulatedDataset(spec=spec, **arrays)


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


def _readable(path: Path) -> bool:
    """Whether the cache file exists; a cache directory that cannot even be searched (mode 000, say) costs a
    warning, as a cache that cannot be written does, and the dataset is simulated."""
    try:
        return path.exists()
    except OSError as exc:
        _cache_warning(f"dataset cache {path.parent} cannot be read ({type(exc).__name__}: {exc}); simulating")
        return False


def get_dataset(spec: DatasetSpec, cache_dir: str | os.PathLike | None = None) -> SimulatedDataset:
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
        _acquire(lock)
    except OSError as exc:
        lock = None
        _cache_warning(
            f"dataset cache {path.parent} cannot be locked ({type(exc).__name__}: {exc}); using it without the lock"
        )
    try:
        if lock is not None:
            _remove_stale_temporaries(path)
        if _readable(path):
            try:
                ds = load_dataset(spec, path)
                log.info("loaded cached dataset %s", path)
                return ds
            except CacheError as exc:
                _cache_warning(f"{exc}; regenerating it")
        log.info("simulating %d roads x %d masses x %d steps -> %s", spec.n_roads, spec.n_masses, spec.n_steps, path)
        ds = generate_dataset(spec)
        try:
            save_dataset(ds, path)
        except OSError as exc:
            _cache_warning(f"dataset not cached at {path} ({type(exc).__name__}: {exc}); using it from memory")
        return ds
    finally:
        if lock is not None:
            lock.release()


def _acquire(lock: FileLock) -> None:
    """Wait for the lock (another job simulating the same dataset), checking for a stop request (core.stop)
    twice a second: a signal must not wait for the other job's dataset."""
    while True:
        try:
            lock.acquire(timeout=0.5)
            return
        except Timeout:
            stop.check()
