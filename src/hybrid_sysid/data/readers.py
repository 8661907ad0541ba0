"""Recordings users bring, read from a CSV or .npz file (formats: docs/predict.md): seat and body accelerations,
their names and sampling interval. Bad input raises InputError naming the file, the item and what is allowed. Read by
hybrid-sysid-predict and load_estimator (inference) and by data=recordings (data.recordings_files)."""

from __future__ import annotations

import csv
import zipfile
import zlib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from hybrid_sysid.core.checks import InputError, Shown, check_dt
from hybrid_sysid.core.memory import tightest_memory
from hybrid_sysid.data.spec import DT_RTOL

CHANNELS = ("seat_acc", "body_acc")
COLUMNS = (*CHANNELS, "time", "recording")  # the CSV columns read; any other is ignored
# A time column's steps may each differ from their mean by this fraction: time stamps rounded to a few
# decimals jitter, a missing sample or a changed rate shows as a step twice the mean or more.
UNIFORM_RTOL = 0.01


@dataclass
class Recordings:
    """What an input file holds: seat and body accelerations (an array, or a list of 1-D arrays), names, dt."""

    seat: object
    body: object
    dt: float
    names: list | None = None


def read_input(path: Path, dt: float | None = None) -> Recordings:
    """A .npz or CSV file (any other suffix) as Recordings; ``dt`` (the dt= argument) stands in for the file's
    time column or dt array, or overrides it when it agrees within UNIFORM_RTOL (for rounded time stamps)."""
    if not path.exists():
        raise InputError("input", Shown(str(path)), "a file that exists")
    if not path.is_file():  # /dev/zero never ends, a FIFO waits for a writer: neither is a recording
        raise InputError("input", Shown(str(path)), "a regular file (a CSV or .npz file), not a device, FIFO or folder")
    if path.is_file() and path.stat().st_size == 0:
        raise InputError(
            "input", Shown(str(path)), "a CSV or .npz file of recordings, not an empty one (docs/predict.md)"
        )
    return read_npz(path, dt) if path.suffix == ".npz" else read_csv(path, dt)


def read_csv(path: Path, dt: float | None) -> Recordings:
    """Columns seat_acc, body_acc, and time (s, uniform) unless dt is given; an optional column ``recording``
    names the recording of each row (several recordings in one file)."""
    try:
        # names as written: read as numbers, "7" and "007" (or "1" and "1.0") would become one recording
        df = pd.read_csv(path, skipinitialspace=True, converters={"recording": str})
    except pd.errors.EmptyDataError:
        raise InputError(
            "input", Shown(str(path)), "a header line and rows, not an empty file (docs/predict.md)"
        ) from None
    except (OSError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise InputError(
            "input", Shown(str(path)), f"a file that can be read as CSV ({type(exc).__name__}: {exc})"
        ) from None
    check_header(path)
    check_present(path, list(map(str, df.columns)), "time", dt, kind="columns")
    if df.empty:
        raise InputError("input", Shown(str(path)), "one row per sample (it holds a header but no rows)")
    columns = [c for c in (*CHANNELS, "time") if c in df.columns]
    for c in columns:
        df[c] = numbers(df[c], path)
    groups = df.groupby("recording", sort=False, dropna=False) if "recording" in df.columns else [(0, df)]
    names, seat, body, steps = [], [], [], []
    for name, g in groups:
        name = name.item() if isinstance(name, np.generic) else name  # a plain int or str in messages
        names.append(name)
        seat.append(g["seat_acc"].to_numpy(np.float64))
        body.append(g["body_acc"].to_numpy(np.float64))
        if "time" in g:
            steps.append((name, uniform_step(g["time"].to_numpy(np.float64), path, name)))
    if dt is not None:  # it stands for every recording's rate: each must agree with it
        for name, s in steps:
            choose_dt(s, dt, path, f"the time step of recording {name!r}")
        return Recordings(seat, body, dt, names)
    (first, step), others = steps[0], steps[1:]
    for name, s in others:
        if abs(s - step) > DT_RTOL * step:
            raise InputError(
                f"input = {path}: the time step of recording {name!r}",
                Shown(f"{s:.9g} s"),
                f"one sample rate per file, recording {first!r}'s {step:.9g} s within {DT_RTOL:g} relative (give dt= "
                "when the time stamps are rounded)",
            )
    return Recordings(seat, body, step, names)


def check_present(path: Path, names: list[str], rate: str, dt: float | None, kind: str, one: str = "") -> None:
    """The file's ``names`` (its ``kind``, columns or arrays) hold seat_acc, body_acc and, without dt=, ``rate``
    (its time column or dt array); ``one``: the word before a missing name in the message."""
    missing = [k for k in (*CHANNELS, *([] if dt is not None else [rate])) if k not in names]
    if missing:
        raise InputError(
            "input",
            Shown(str(path)),
            f"{kind} seat_acc, body_acc, and {rate} or dt= (it has no {one}{', '.join(missing)}; its {kind}: "
            f"{', '.join(names)})",
        )


def check_header(path: Path) -> None:
    """Each column read (COLUMNS) named once in the header line: pandas would rename a second seat_acc to
    seat_acc.1 and read only the first. The header is read as pandas reads it (the first line that is not
    blank, spaces after commas skipped)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            header = next((row for row in csv.reader(f, skipinitialspace=True) if row), [])
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(
            "input", Shown(str(path)), f"a file that can be read as CSV ({type(exc).__name__}: {exc})"
        ) from None
    counts = Counter(header)
    for name in COLUMNS:
        if counts[name] > 1:
            where = [str(i + 1) for i, h in enumerate(header) if h == name]
            raise InputError(
                f"input = {path}: column {name}",
                Shown(f"{counts[name]} times in the header (columns {', '.join(where)})"),
                f"each of {', '.join(COLUMNS)} once",
            )


def numbers(column: pd.Series, path: Path) -> pd.Series:
    """The column as floats; text that is not a number is an error (empty cells become NaN, which the
    estimator reports with the recording and step), and so are true/false cells (pandas reads them as bool,
    which would count as 1 and 0)."""
    if column.dtype.kind == "b":  # every cell true or false
        flags = np.arange(len(column))
    elif column.dtype.kind == "O":  # true/false among empty cells or text
        flags = np.flatnonzero(column.map(lambda v: isinstance(v, (bool, np.bool_))).to_numpy(bool))
    else:
        flags = np.array([], dtype=int)
    if flags.size:
        flag = bool(column.iloc[flags[0]])
        raise InputError(
            f"input = {path}: column {column.name} in data row {flags[0] + 1}", flag, "numbers, not true/false"
        )
    values = pd.to_numeric(column, errors="coerce")
    bad = np.flatnonzero(values.isna().to_numpy() & column.notna().to_numpy())
    if bad.size:
        raise InputError(
            f"input = {path}: column {column.name} in data row {bad[0] + 1}", column.iloc[bad[0]], "numbers"
        )
    return values


def uniform_step(t: np.ndarray, path: Path, name) -> float:
    """The time column's step, (t_last - t_first) / (n - 1), after checking every step lies near it."""
    where = f"input = {path}: column time of recording {name!r}"
    if not np.isfinite(t).all():
        raise InputError(where, float(t[~np.isfinite(t)][0]), "finite times in seconds")
    if len(t) < 2:
        raise InputError(where, Shown(f"{len(t)} row"), "at least 2 rows to give the step")
    step, steps = (t[-1] - t[0]) / (len(t) - 1), np.diff(t)
    off = np.flatnonzero(np.abs(steps - step) > UNIFORM_RTOL * abs(step)) if step > 0 else [0]
    if len(off):
        k = off[0]
        raise InputError(
            where,
            Shown(f"a step of {steps[k]:g} s from {t[k]:g} s to {t[k + 1]:g} s"),
            f"uniform, increasing times, every step within {UNIFORM_RTOL:.0%} of the mean, {step:g} s",
        )
    return float(step)


def choose_dt(file_dt: float, dt: float | None, path: Path, what: str) -> float:
    """dt= when given (it must agree with the file within UNIFORM_RTOL), else the file's own dt."""
    if dt is None:
        return file_dt
    if abs(file_dt - dt) > UNIFORM_RTOL * dt:
        raise InputError(
            "dt", dt, f"{what} of input = {path}, {file_dt:g} s, within {UNIFORM_RTOL:.0%}, or no dt= at all"
        )
    return dt


def read_npz(path: Path, dt: float | None) -> Recordings:
    """Arrays seat_acc and body_acc, 1-D (one recording) or 2-D (recordings, steps), and a scalar dt in s."""
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(
            "input", Shown(str(path)), f"a file that can be read as .npz ({type(exc).__name__}: {exc})"
        ) from None
    if not isinstance(loaded, np.lib.npyio.NpzFile):  # a plain .npy array under an .npz name
        raise InputError(
            "input",
            Shown(str(path)),
            "an .npz file with named arrays seat_acc, body_acc and dt (numpy.savez); it is a single .npy array, "
            "not an .npz archive",
        )
    with loaded as z:
        check_present(path, z.files, "dt", dt, kind="arrays", one="array ")
        # only the arrays read: another array (an object array, a huge one) is never loaded
        arrays = {k: npz_array(z, k, path) for k in (*CHANNELS, "dt") if k in z.files}
    for k in CHANNELS:
        a = arrays[k]
        if a.dtype.kind not in "fiu" or a.ndim not in (1, 2) or a.size == 0:
            raise InputError(
                f"input = {path}: array {k}",
                Shown(f"dtype {a.dtype}, shape {a.shape}"),
                "real numbers (a float or integer array, not bool or complex), 1-D (one recording) or 2-D "
                "(recordings, steps), not empty",
            )
    if "dt" in arrays:
        a = arrays["dt"]
        number = a.item() if a.dtype.kind in "fiu" and a.size == 1 else None  # None: refused, shown as it is
        where = f"input = {path}: array dt"
        file_dt = check_dt(number, where, "one number > 0 (seconds)", InputError, shown=a.tolist())
        dt = choose_dt(file_dt, dt, path, "the array dt")
    return Recordings(arrays["seat_acc"], arrays["body_acc"], dt)


# the .npy header versions numpy reads publicly; version 3.0 (UTF-8 field names, no float arrays) is left to np.load
HEADER_READERS = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}


def npz_array(z: np.lib.npyio.NpzFile, key: str, path: Path) -> np.ndarray:
    """One array of an .npz file, after its header: a compressed member may declare far more than the file's
    size (a few MB of zeros unpack to GBs), so the size it declares must fit in the memory the process may still
    use before it is unpacked. A damaged member (bad CRC, cut short) or an object array is one InputError."""
    where = f"input = {path}: array {key}"
    try:
        with z.zip.open(f"{key}.npy") as f:
            read_header = HEADER_READERS.get(np.lib.format.read_magic(f))
            shape, _, dtype = read_header(f) if read_header else ((), False, np.dtype(np.uint8))
        size = int(np.prod(shape, dtype=object)) * dtype.itemsize
        tightest = tightest_memory()
        if tightest is not None and size > tightest[0]:
            raise InputError(
                where,
                Shown(f"shape {shape}, {size / 2**30:.3g} GiB"),
                f"arrays that fit in the memory available, {tightest[0] / 2**30:.3g} GiB ({tightest[1]})",
            )
        return z[key]
    except InputError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise InputError(where, allowed=f"an array that can be read ({type(exc).__name__}: {exc})") from None
