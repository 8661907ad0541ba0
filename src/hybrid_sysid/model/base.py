"""What the rest of the package asks of a network, an objective, a baseline and a data module, declared here once.

Each is a Protocol: a class meets it by having the members, without inheriting anything, so a class of one's own
(a researcher's network, say) needs no import of this package's classes. ``lacks(cls, protocol)`` names the
members a class does not have; the config layer refuses a ``_target_`` whose class lacks any (config/targets.py).
docs/extend/network.md and docs/extend/objective.md show a class of each kind; docs/extending.md, one in a
package of its own (a plugin, declared by an entry point: config/plugins.py).
"""

from __future__ import annotations

from typing import ClassVar, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class SplitPredictor(Protocol):
    """What the evaluation asks of every estimator, a network's LightningModule and a baseline alike."""

    def predict_split(
        self, dm, split: str, noise_std: float, limit: int | None = None, windows: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """(pred, true), float64 (recordings, 2): p1, p2 per recording of ``split`` (its first ``limit``) at noise
        std ``noise_std``, the prediction being the mean over ``windows`` = K fixed windows per recording."""


class Network(Protocol):
    """A torch module that maps windows (B, 2, W), channel 0 seat z'' and channel 1 body y'' in m/s^2, to (B, 2)
    positive p = (p1, p2) in 1/s and 1/s^2. Optional: ``auxiliary``, a tuple of further (B, 2) estimates its last
    training forward made, each of which training adds the objective of to the loss (model.anchored's partner)."""

    # the constructor's arguments that carry the prior of p (the config derives them: ${p_prior:...}), not the
    # architecture: a trained network's weights load into a network built with other values of them
    prior_arguments: ClassVar[tuple[str, ...]]

    @staticmethod
    def window_bounds(**arguments) -> tuple[int, int | None]:
        """The shortest and the longest window (None: any) a network built with ``arguments`` reads."""

    def output_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The lowest and highest p (two arrays of 2) its head can give, as its weights hold them; None when the
        head is unbounded."""

    def __call__(self, signals): ...


class Objective(Protocol):
    """A torch module ``loss = objective(pred, batch)``: pred (B, 2) p in physical units, batch the data module's
    dict (hybrid_sysid.data.windows: "signals", "params", "rel_vel", "rel_disp"; with ``fir``, "seat_f",
    "rel_vel_f", "rel_disp_f"; with ``outside_fir``, "p_out", "se_out")."""

    uses_labels: bool  # whether it reads batch["params"]; a label-free objective never does
    fir: np.ndarray | None  # the band-pass taps the batches must carry filtered signals through (None: none)
    # the band-pass of the least-squares fit over each window's outside samples (the rest of its recording): the
    # batches then carry that fit's "p_out" and "se_out" (B, 2); None: not needed
    outside_fir: np.ndarray | None
    monitor: str  # its model-selection figure under trainer.monitor=auto: val/rel_dev reads labels, val/loss not

    def __call__(self, pred, batch): ...


class Baseline(SplitPredictor, Protocol):
    """An estimator without a network (baseline=): evaluated like one, and an estimator of recordings."""

    fit_seconds: float  # the time its fits took so far: a baseline's only work, its run's train_seconds

    def check_lengths(self, window: int, n_steps: int) -> None:
        """ConfigError when what it filters (a window, or a whole recording) is too short for it."""

    def estimate(self, seat, body, dt: float, measurement: str, window: int, windows: int) -> np.ndarray:
        """(K, 2) estimates of one recording (float64 arrays in m/s^2 at the step ``dt``): per window, at
        ``windows`` = K evenly spaced starts, or one estimate of the whole recording."""


class DataModule(Protocol):
    """A LightningDataModule of recordings with their true p, cut into windows: data.module's class (a plugin's,
    docs/extending.md). Its batches are dicts of tensors: "signals" (B, 2, W) float32, seat z'' and body y'' in
    m/s^2, "params" (B, 2) the true p, and what the objective reads (Objective: "rel_vel" and "rel_disp" for the
    hybrid objectives). Its constructor loads nothing (the checks before any work build it): ``setup`` does."""

    window: int  # W, the steps of a window: data.window, the length the network is checked on
    # after setup, the recordings ``rows`` index: road_class (n,) a label per recording (the table per class), m3
    # (n,) the seat mass in kg, and spec with dt in s and measurement (physics.eiv.eiv_model's: the Cramér-Rao bound)
    dataset: object

    def setup(self, stage: str | None = None) -> None: ...

    def train_dataloader(self):
        """Training batches, as many as trainer.max_steps takes (an endless stream, say)."""

    def val_dataloader(self):
        """The validation windows' batches, which model selection reads (val/loss, val/rel_dev)."""

    def rows(self, split: str) -> np.ndarray:
        """The recordings of ``split`` (train, val or test): indices into ``dataset``'s arrays, in the order of
        the split's fixed windows."""

    def eval_batch(self, split: str, noise_std: float = 0.0, limit: int | None = None, windows: int = 1) -> dict:
        """A batch of the split's fixed, seeded windows (of its first ``limit`` recordings) with Gaussian noise of
        std ``noise_std`` on both channels; ``windows`` = K per recording, row i * K + j window j of recording i."""

    def eval_dataloader(self, split: str, noise_std: float = 0.0, limit: int | None = None, windows: int = 1):
        """The batches of eval_batch's windows, in its order."""


def members(protocol: type) -> list[str]:
    """The names a class must have to meet ``protocol`` (one of this module's), in the order they are declared."""
    names = []
    for base in reversed(protocol.__mro__):
        if base.__module__ == __name__:
            declared = [*getattr(base, "__annotations__", {}), *vars(base)]
            names += [n for n in declared if not n.startswith("_") or n == "__call__"]
    return list(dict.fromkeys(names))


def lacks(cls, protocol: type) -> list[str]:
    """The members of ``protocol`` that ``cls`` (a class, or an object) does not have."""
    return [name for name in members(protocol) if not hasattr(cls, name)]
