"""Simulated datasets (spec, generation, the on-disk cache, the split by road: numpy and the compiled kernel, no
torch) and, in ``datamodule`` and ``windows``, the LightningDataModule that cuts them into windows."""

from hybrid_sysid.data.cache import get_dataset
from hybrid_sysid.data.dataset import SimulatedDataset, generate_dataset
from hybrid_sysid.data.spec import DatasetSpec, WindowSettings
from hybrid_sysid.data.splits import SPLITS, Split, split_by_road

__all__ = [
    "SPLITS",
    "DatasetSpec",
    "SimulatedDataset",
    "Split",
    "WindowSettings",
    "generate_dataset",
    "get_dataset",
    "split_by_road",
]
