"""A user's recordings on disk (``data=recordings``): which files ``data.path`` names, what each holds, and its
fingerprint. The files are read by hybrid-sysid-predict's readers (data.readers, formats: docs/predict.md),
one at a time: a scan keeps each recording's name, file and length, never its samples, so a folder of any size is
indexed in the memory of its largest file. Bad files raise ConfigError, one line naming the file and what is wrong.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hybrid_sysid.core.checks import ConfigError, Shown, bad
from hybrid_sysid.data.spec import DT_RTOL
from hybrid_sysid.data.splits import SPLITS, Split, split_by_road

KEY = "data.path"
SUFFIXES = (".csv", ".npz")  # what a folder's files are read as; a single file named by data.path may end in any
CHUNK = 2**20  # bytes hashed at a time
# data.path of a run's saved config once read back (runs.received): files of the machine it ran on are data, read
# only when a command names them again
UNNAMED = "(a saved run's files: name them again, data.path=...)"


@dataclass(frozen=True)
class Recorded:
    """One recording of data.path: its name, the file that holds it (relative to data.path) and its samples."""

    name: str
    file: str
    steps: int


@dataclass
class RecordingsIndex:
    """What data.path holds, without its samples: the recordings in file order, their common step (s), and each
    file's fingerprint (name, bytes, sha256)."""

    root: Path
    recordings: list[Recorded]
    dt: float
    files: list[dict] = field(default_factory=list)

    def path_of(self, file: str) -> Path:
        return self.root / file if self.root.is_dir() else self.root

    @property
    def steps(self) -> np.ndarray:
        return np.array([r.steps for r in self.recordings], dtype=np.int64)

    def fingerprint(self) -> dict:
        """The record's account of the files trained and tested on: never their samples."""
        return {"path": str(self.root), "recordings": len(self.recordings), "dt": self.dt, "files": self.files}


def recording_files(path: Path) -> list[Path]:
    """The files of data.path: the file itself, or the .csv and .npz files of a folder (not its subfolders), by name."""
    if not path.exists():
        bad(KEY, Shown(str(path)), "a CSV or .npz file of recordings, or a folder of them, that exists")
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix in SUFFIXES and not p.name.startswith(".") and p.is_file())
        if not files:
            bad(KEY, Shown(str(path)), "a folder holding recordings, .csv or .npz files (it holds none)")
        return files
    if not path.is_file():  # a FIFO waits for a writer, a device never ends: neither is a recording
        bad(KEY, Shown(str(path)), "a regular file (a CSV or .npz file) or a folder of them")
    return [path]


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(CHUNK):
            digest.update(block)
    return digest.hexdigest()


def file_print(path: Path, name: str) -> dict:
    """A file as the record names it: its name, size and sha256."""
    return {"name": name, "bytes": path.stat().st_size, "sha256": sha256(path)}


def as_data_error(exc: ConfigError) -> ConfigError:
    """A reader's InputError ("input = <file>: ...") under data.path, the key a user set."""
    key = exc.key
    key = KEY + key[len("input") :] if key.startswith("input") else f"{KEY}: {key}"
    return ConfigError(key, exc.value, exc.allowed, exc.missing)


def read_file(path: Path):
    """(names, seats, bodies, dt) of one file: hybrid-sysid-predict's reader, its errors under data.path. A name
    is the file's ``recording`` column (as written); without one, the file's stem, with ``:i`` for row i of an
    .npz file's 2-D arrays."""
    from hybrid_sysid.data.readers import read_input  # deferred

    try:
        rec = read_input(path)
    except ConfigError as exc:
        raise as_data_error(exc) from None
    if isinstance(rec.seat, list):  # a CSV: a name per recording, 0 when it has no recording column
        names = [n if isinstance(n, str) else path.stem for n in rec.names]
        return names, rec.seat, rec.body, float(rec.dt)
    seat, body = np.asarray(rec.seat), np.asarray(rec.body)
    if seat.shape != body.shape:
        bad(f"{KEY} = {path}: array body_acc", Shown(f"shape {body.shape}"), f"the shape of seat_acc, {seat.shape}")
    if seat.ndim == 1:
        return [path.stem], [seat], [body], float(rec.dt)
    return [f"{path.stem}:{i}" for i in range(len(seat))], list(seat), list(body), float(rec.dt)


def check_finite(path: Path, name: str, seat: np.ndarray, body: np.ndarray) -> None:
    """Every sample a number: a NaN (an empty CSV cell) or inf would poison every window that holds it."""
    for channel, x in (("seat_acc", seat), ("body_acc", body)):
        bad_steps = np.flatnonzero(~np.isfinite(np.asarray(x, dtype=np.float64)))
        if bad_steps.size:
            bad(
                f"{KEY} = {path}: recording {name!r}, {channel}",
                Shown(f"{x[bad_steps[0]]} at step {bad_steps[0]} ({bad_steps.size} non-finite in all)"),
                "finite accelerations in m/s^2 in every sample (cut the recording where it has gaps)",
            )


def scan(root: Path) -> RecordingsIndex:
    """Every file of data.path read once, in name order, for its recordings' names and lengths, its step and its
    fingerprint; one ConfigError at the first bad file. Names are unique across data.path."""
    files = recording_files(root)
    recordings, where, prints, dt, first = [], {}, [], None, None
    for path in files:
        names, seats, bodies, step = read_file(path)
        relative = path.name
        if dt is None:
            dt, first = step, relative
        elif abs(step - dt) > DT_RTOL * dt:  # files share one sample rate, as a file's recordings do
            bad(
                f"{KEY} = {path}: its time step",
                Shown(f"{step:.9g} s"),
                f"one sample rate across data.path, {first}'s {dt:.9g} s within {DT_RTOL:g} relative (resample the "
                "files to one rate first)",
            )
        for name, seat, body in zip(names, seats, bodies):
            check_finite(path, name, seat, body)
            if name in where:
                bad(
                    f"{KEY} = {path}: recording {name!r}",
                    Shown(f"also in {where[name]}"),
                    "names unique across data.path (a file's recording column, else its name)",
                )
            where[name] = relative
            recordings.append(Recorded(name, relative, len(seat)))
        prints.append(file_print(path, relative))
    if not recordings:
        bad(KEY, Shown(str(root)), "files holding at least one recording")
    return RecordingsIndex(root, recordings, float(dt), prints)


_SCANS: dict = {}  # one scan per folder state and process: the preflight's, reused by the run it checked


def index(path) -> RecordingsIndex:
    """``scan`` of data.path, cached while no file of it changes (names, sizes, modification times)."""
    root = Path(str(path)).expanduser()
    files = recording_files(root)
    state = tuple((str(p), p.stat().st_size, p.stat().st_mtime_ns) for p in files)
    key = (str(root.resolve()), state)
    if key not in _SCANS:
        _SCANS.clear()  # one folder at a time: a sweep's worker keeps no index of an earlier job's files
        _SCANS[key] = scan(root)
    return _SCANS[key]


def read_recordings(idx: RecordingsIndex, wanted: list[int]):
    """Yield (position in ``wanted``, seat, body) of the recordings ``wanted`` (indices into idx.recordings), file
    by file: only one file's samples are held at a time besides what the caller keeps."""
    by_file: dict[str, dict[str, int]] = {}
    for pos, i in enumerate(wanted):
        r = idx.recordings[i]
        by_file.setdefault(r.file, {})[r.name] = pos
    for file, names in by_file.items():
        path = idx.path_of(file)
        got, seats, bodies, _ = read_file(path)
        for name, seat, body in zip(got, seats, bodies):
            if name in names:
                yield names[name], np.asarray(seat, dtype=np.float64), np.asarray(body, dtype=np.float64)
        missing = set(names) - set(got)
        if missing:  # the file changed since it was scanned
            bad(f"{KEY} = {path}", Shown(f"no recording {sorted(missing)[0]!r}"), "the files as they were scanned")


def split_recordings(n: int, train_fraction: float, val_fraction: float, seed: int) -> Split:
    """Train, validation and test recordings (indices, ascending): data.splits' counts on a seeded permutation,
    so each recording falls in one split and the same data.seed always splits alike."""
    try:
        by_position = split_by_road(n, 1, train_fraction, val_fraction)
    except ConfigError as exc:
        if exc.key != "n_roads":
            raise
        bad("data.path", Shown(f"{n} recordings"), exc.allowed.replace(" road", " recording"))
    order = np.random.default_rng(seed).permutation(n)
    return Split(*(np.sort(order[getattr(by_position, s)]) for s in SPLITS))
