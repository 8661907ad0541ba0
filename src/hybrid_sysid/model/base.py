"""What every estimator meets, a network's LightningModule and a baseline without a network alike: predictions
and truth on a split's fixed evaluation windows (hybrid_sysid.training.evaluation scores them)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class SplitPredictor(Protocol):
    def predict_split(
        self, dm, split: str, noise_std: float, limit: int | None = None, windows: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """(pred, true), float64 (recordings, 2): p1, p2 per recording of ``split`` (its first ``limit``) at noise
        std ``noise_std``, the prediction being the mean over ``windows`` = K fixed windows per recording."""
