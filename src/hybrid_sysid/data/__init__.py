"""Simulated datasets, their on-disk cache and the split by road (numpy and the compiled kernel; no torch).

The LightningDataModule that cuts recordings into windows is ``hybrid_sysid.data.datamodule.QCMDataModule``.
"""

from hybrid_sysid.data.dataset import DatasetSpec, QCMDataset, generate_dataset, get_dataset
from hybrid_sysid.data.splits import SPLITS, Split, split_by_road

__all__ = ["SPLITS", "DatasetSpec", "QCMDataset", "Split", "generate_dataset", "get_dataset", "split_by_road"]
