"""The data module of a config with data.path (``data=recordings``, data.recordings): a user's files, their labels
when data.labels names some, and the errors-in-variables fit of each whole recording as the reference without."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.data.recordings import RecordingsDataModule
from hybrid_sysid.data.recordings_files import file_print, index, split_recordings
from hybrid_sysid.data.recordings_labels import read_labels
from hybrid_sysid.training.data_arguments import window_arguments


def whole_recording_fit(seat: np.ndarray, body: np.ndarray, dt: float, measurement: str) -> np.ndarray:
    """The errors-in-variables maximum-likelihood fit of whole recordings (n, steps), both channels noisy in the
    simulator's ratio: estimator=eiv's fit (conf/baseline/eiv.yaml's defaults) over every sample."""
    return ErrorsInVariablesFit(dt=dt).fit(seat, body, dt, measurement)


def recordings_datamodule(cfg: DictConfig, objective=None) -> RecordingsDataModule:
    """build_datamodule's, for data.path: ``objective`` the run's (None for a baseline)."""
    d = cfg.data
    idx = index(d.path)
    labels, labels_file = None, None
    if d.get("labels") is not None:
        path = Path(str(d.labels)).expanduser()
        labels, labels_file = read_labels(path, [r.name for r in idx.recordings]), file_print(path, path.name)
    return RecordingsDataModule(
        idx,
        split_recordings(len(idx.recordings), d.train_fraction, d.val_fraction, d.seed),
        d.measurement,
        whole_recording_fit,
        labels,
        labels_file,
        **window_arguments(cfg, objective),
    )
