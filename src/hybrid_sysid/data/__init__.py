"""Simulated datasets (spec, generation, the on-disk cache, the split by road: numpy and the compiled kernel, no
torch) and, in ``datamodule`` and ``windows``, the LightningDataModule that cuts them into windows. spec and splits
load with the package; generation and the cache, which load the compiler (numba), when first named."""

import importlib

from hybrid_sysid.data.spec import DatasetSpec, WindowSettings
from hybrid_sysid.data.splits import SPLITS, Split, split_by_road

_LAZY = {"get_dataset": "cache", "SimulatedDataset": "dataset", "generate_dataset": "dataset"}

__all__ = ["SPLITS", "DatasetSpec", "Split", "WindowSettings", "split_by_road", *_LAZY]


def __getattr__(name):
    # the config's checks, which every command runs, import data.spec without the compiler
    if name in _LAZY:
        return getattr(importlib.import_module(f"hybrid_sysid.data.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
