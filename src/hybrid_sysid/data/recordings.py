"""``data=recordings``: a LightningDataModule over a user's own recordings (data.path, read by
data.recordings_files), served to training, evaluation and the report as the simulated data module serves its own:
the same windows, noise and batches (it is a QuarterCarDataModule whose recordings come from files).

Recordings are split into train, validation and test by recording, with data.seed. A split's samples are read
from the files when it is first needed: the training split stays in memory while the run lives, every other split
only until another one is asked for (its fixed evaluation windows stay cached, as the simulated module's do). So a
folder of any number of recordings takes the training split's memory, plus one other split's.

Each recording's "params" are its labels (data.labels) or, without labels, the errors-in-variables fit over the
whole recording (``reference``): the test rows then measure each estimate against that fit. Recordings of
different lengths are zero-padded to the longest; window starts are drawn within each recording's own length.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import lightning as L
import numpy as np

from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.data.recordings_files import RecordingsIndex, read_recordings
from hybrid_sysid.data.serving import Serving, takes_serving
from hybrid_sysid.data.spec import starts_offered
from hybrid_sysid.data.splits import Split
from hybrid_sysid.data.windows import WindowCutter
from hybrid_sysid.physics import relative_states

REFERENCE = "fit over the whole recording"  # what the test rows measure against without labels
# recordings fitted at once: the fit's float64 work arrays grow with it (7,000 recordings of 1,200 steps at once
# took the run's peak memory from 0.97 to 1.45 GB)
FIT_CHUNK = 256
LABELLED = "labels"


@dataclass(frozen=True)
class RecordedSpec:
    """What the window code reads of a dataset's spec: the step, the measurement and the (padded) length."""

    dt: float
    measurement: str
    n_steps: int


@dataclass
class RecordedSplit:
    """One split's recordings as the window code reads a simulated dataset: float32 channels (n, n_steps),
    zero-padded past each recording's ``lengths``; ``params`` its labels or reference fits."""

    spec: RecordedSpec
    seat_acc: np.ndarray
    body_acc: np.ndarray
    rel_vel: np.ndarray
    rel_disp: np.ndarray
    params: np.ndarray
    lengths: np.ndarray


@dataclass(frozen=True)
class DatasetView:
    """``dm.dataset`` of a recordings module: the spec alone, since no one split is the dataset."""

    spec: RecordedSpec


# the fit of whole recordings without labels: (seat, body) float64 (n, steps), dt, measurement -> (n, 2) p
Fit = Callable[[np.ndarray, np.ndarray, float, str], np.ndarray]


def reference_fits(fit: Fit, seat: np.ndarray, body: np.ndarray, lengths: np.ndarray, dt: float, measurement: str):
    """(n, 2) fits of whole recordings (float64 of the stored float32 channels, so a window spanning a whole
    recording is fitted to the same numbers), recordings of one length fitted together, FIT_CHUNK at a time."""
    out = np.empty((len(lengths), 2))
    for n in np.unique(lengths):
        same = np.flatnonzero(lengths == n)
        for rows in np.array_split(same, -(-len(same) // FIT_CHUNK)):
            out[rows] = fit(seat[rows, :n].astype(np.float64), body[rows, :n].astype(np.float64), dt, measurement)
    return out


def load_split(idx: RecordingsIndex, wanted: np.ndarray, spec: RecordedSpec, params: np.ndarray | None, fit: Fit):
    """The recordings ``wanted`` read from their files into a RecordedSplit; ``params`` None: ``fit``'s."""
    n, steps = len(wanted), spec.n_steps
    arrays = [np.zeros((n, steps), dtype=np.float32) for _ in range(4)]
    lengths = idx.steps[wanted]
    for pos, seat, body in read_recordings(idx, list(wanted)):
        k = len(seat)
        rel_vel, rel_disp = relative_states(seat, body, spec.dt, spec.measurement)
        for a, x in zip(arrays, (seat, body, rel_vel, rel_disp)):
            a[pos, :k] = x
    if params is None:
        params = reference_fits(fit, arrays[0], arrays[1], lengths, spec.dt, spec.measurement)
    return RecordedSplit(spec, *arrays, params=params, lengths=lengths)


class RecordingsDataModule(QuarterCarDataModule):
    """The recordings of data.path in windows (module docstring). ``labels``: (params (n, 2), m3 (n,)) in the
    index's order, or None, and ``labels_file`` their file's fingerprint; ``reference``: the fit of whole recordings
    without labels (training.recordings passes the errors-in-variables fit); ``serving``: Serving's keyword
    arguments, as QuarterCarDataModule takes them."""

    @takes_serving
    def __init__(
        self,
        idx: RecordingsIndex,
        split: Split,
        measurement: str,
        reference: Fit,
        labels: tuple[np.ndarray, np.ndarray] | None = None,
        labels_file: dict | None = None,
        **serving,
    ):
        L.LightningDataModule.__init__(self)  # the simulated module's own __init__ reads a simulation's spec
        self._serve(Serving(**serving))
        self.index, self.split, self.labels, self.reference_fit = idx, split, labels, reference
        self.labels_file = labels_file
        self.spec = RecordedSpec(idx.dt, measurement, int(idx.steps.max()))
        self.dataset = DatasetView(self.spec)
        self.cache_dir = None
        self._other: tuple[str, WindowCutter] | None = None  # the one other split whose samples are held
        self._params: dict[str, np.ndarray] = {}  # each split's reference fits, once computed

    @property
    def reference(self) -> str:
        """What the scores measure each estimate against: the labels, or the fit over the whole recording."""
        return LABELLED if self.labels is not None else REFERENCE

    def prepare_data(self) -> None:
        pass  # the files are read where they are, split by split

    def _training_cutter(self) -> WindowCutter:
        return self._load("train")

    def _load(self, split: str) -> WindowCutter:
        wanted = getattr(self.split, split)
        params = self._params.get(split)
        if params is None and self.labels is not None:
            params = self.labels[0][wanted]
        ds = load_split(self.index, wanted, self.spec, params, self.reference_fit)
        self._params[split] = ds.params
        return self._cut(ds)

    def cutter(self, split: str) -> WindowCutter:
        """The training split's windows, or another split's, read from the files when it is not the one held."""
        self.setup()
        if split == "train":
            return self.data
        if self._other is None or self._other[0] != split:
            self._other = None  # released before the next split is read: one other split in memory at a time
            self._other = (split, self._load(split))
        return self._other[1]

    @property
    def held_splits(self) -> tuple[str, ...]:
        """The splits whose samples are in memory now: the training split once set up, and one other."""
        return (("train",) if self.data is not None else ()) + ((self._other[0],) if self._other else ())

    def rows(self, split: str) -> np.ndarray:
        return np.arange(len(getattr(self.split, split)))

    def n_starts(self) -> int:
        """How many window starts the shortest recording offers (a K must fit in every recording)."""
        return int(starts_offered(self.index.steps.min(), self.window))

    def recording_columns(self, split: str) -> dict[str, np.ndarray]:
        """predictions.csv's columns of the split's recordings: their names, no road class, m3 when labelled."""
        wanted = getattr(self.split, split)
        names = np.array([self.index.recordings[i].name for i in wanted], dtype=object)
        m3 = self.labels[1][wanted] if self.labels is not None else np.full(len(wanted), np.nan)
        return {"recording": names, "road_class": np.full(len(wanted), np.nan), "m3": m3}

    def record_fields(self) -> dict:
        """The record's account of the data: the files' fingerprint and what the scores measure against."""
        files = self.index.fingerprint()
        if self.labels_file is not None:
            files["labels"] = self.labels_file
        return {"data_files": files, "reference": self.reference}
