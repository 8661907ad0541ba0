"""Simulated datasets, their cache, and the LightningDataModule that cuts them into windows.

Generating or loading a dataset needs numpy only: the torch side (QCMDataModule, split_by_road) is imported on
first use, so a process that only generates data does not carry torch and Lightning (~0.5 GiB resident).
"""

from hybrid_sysid.data.dataset import DatasetSpec, QCMDataset, generate_dataset, get_dataset

__all__ = ["DatasetSpec", "QCMDataModule", "QCMDataset", "generate_dataset", "get_dataset", "split_by_road"]
_LAZY = {"QCMDataModule", "split_by_road"}


def __getattr__(name):
    if name in _LAZY:
        from hybrid_sysid.data import datamodule
        return getattr(datamodule, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
