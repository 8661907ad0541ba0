"""Simulated datasets, their cache, and the LightningDataModule that cuts them into windows."""

from hybrid_sysid.data.datamodule import QCMDataModule, split_by_road
from hybrid_sysid.data.dataset import DatasetSpec, QCMDataset, generate_dataset, get_dataset

__all__ = ["DatasetSpec", "QCMDataModule", "QCMDataset", "generate_dataset", "get_dataset", "split_by_road"]
