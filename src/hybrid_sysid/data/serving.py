"""``Serving``: the keyword arguments every built-in data module takes besides its recordings (the simulated
QuarterCarDataModule, data.recordings' files): the window and its noise's re-integration, the batches and their
noise, the run's seed, and the signals the objective reads. Each default is its owner's (``WindowSettings``,
``BatchSettings``) or written here once; ``takes_serving`` makes them a module's keyword arguments.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, fields

import numpy as np

from hybrid_sysid.data.spec import BatchSettings, WindowSettings


@dataclass(frozen=True, eq=False)  # eq=False: the taps are arrays, which == compares element by element
class Serving:
    """How a data module cuts and serves its recordings; the ranges are checked by ``WindowSettings.validate``
    (window, integration: against the recordings) and ``BatchSettings.validate`` (``batches``)."""

    window: int = WindowSettings.window
    batch_size: int = BatchSettings.batch_size
    eval_batch_size: int = 256  # windows per evaluation batch (eval_dataloader)
    train_std: float = BatchSettings.train_std
    seed: int = 0  # the run's: the training stream and the fixed evaluation windows draw from it
    integration: str = WindowSettings.integration
    fir: np.ndarray | None = None  # the objective's band-pass taps (None: no filtered signals in the batches)
    train_std_max: float | None = BatchSettings.train_std_max
    outside_fir: np.ndarray | None = None  # the band-pass of the fit over each window's outside samples
    outside_target: str | None = None  # that fit, "eiv" or "ls" (None: "ls")
    outside_fix: str = "none"  # the recording fault's fix that fit takes ("eiv" only; data.outside)

    @property
    def batches(self) -> BatchSettings:
        return BatchSettings(self.batch_size, self.train_std, self.train_std_max)


def takes_serving(init):
    """Decorates a data module's ``__init__(self, ..., **serving)``: its signature lists Serving's fields as
    keyword-only arguments with their defaults, so help() shows them and config.targets checks a data.module's
    arguments by name, as it did when each module wrote them out."""
    sig = inspect.signature(init)
    own = [p for p in sig.parameters.values() if p.kind is not p.VAR_KEYWORD]
    keyword = inspect.Parameter.KEYWORD_ONLY
    served = [inspect.Parameter(f.name, keyword, default=f.default, annotation=f.type) for f in fields(Serving)]
    init.__signature__ = sig.replace(parameters=own + served)
    return init
