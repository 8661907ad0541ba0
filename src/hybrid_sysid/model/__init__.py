"""Parameter estimators (CNNs), training objectives (labelled, hybrid, combined, cross_segment), the
LightningModule around them, what each of them provides (base: the Network, Objective and Baseline protocols) and
the relative deviation (eq. 24, metrics). base, metrics and optim load no torch; the classes below load it when
first named."""

import importlib

from hybrid_sysid.model.base import Baseline, Network, Objective, SplitPredictor

_LAZY = {
    "FastCNN": "networks",
    "PaperCNN": "networks",
    "AnchoredCNN": "anchored",
    "LabelledObjective": "objectives",
    "HybridObjective": "objectives",
    "CombinedObjective": "objectives",
    "CrossSegmentObjective": "cross_segment",
    "IdentificationModule": "module",
}

__all__ = ["Baseline", "Network", "Objective", "SplitPredictor", *_LAZY]


def __getattr__(name):
    # the report and the config's checks import model.metrics and model.base without torch
    if name in _LAZY:
        return getattr(importlib.import_module(f"hybrid_sysid.model.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
