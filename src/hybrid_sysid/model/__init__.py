"""Parameter estimators (CNNs), training objectives (labelled, hybrid, combined), the LightningModule around them
and the protocol every estimator meets (base.SplitPredictor)."""

from hybrid_sysid.model.base import SplitPredictor
from hybrid_sysid.model.networks import FastCNN, PaperCNN
from hybrid_sysid.model.objectives import CombinedObjective, HybridObjective, LabelledObjective

__all__ = [
    "CombinedObjective",
    "FastCNN",
    "HybridObjective",
    "LabelledObjective",
    "PaperCNN",
    "SplitPredictor",
]
