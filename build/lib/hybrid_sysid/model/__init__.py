"""Parameter estimators (CNNs) and training objectives (labelled, hybrid, combined)."""

from hybrid_sysid.model.networks import FastCNN, PaperCNN
from hybrid_sysid.model.objectives import CombinedObjective, HybridObjective, LabelledObjective

__all__ = [
    "CombinedObjective",
    "FastCNN",
    "HybridObjective",
    "LabelledObjective",
    "PaperCNN",
]
