"""Parameter estimators (CNNs) and training objectives (labelled, hybrid, combined)."""

from hybrid_sysid.model.networks import P_MAX, P_MIN, FastCNN, PaperCNN
from hybrid_sysid.model.objectives import CombinedObjective, HybridObjective, LabelledObjective

__all__ = [
    "P_MAX",
    "P_MIN",
    "CombinedObjective",
    "FastCNN",
    "HybridObjective",
    "LabelledObjective",
    "PaperCNN",
]
