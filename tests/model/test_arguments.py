"""model.arguments, the torch-free part of each of the package's networks and objectives: config validation runs it
before torch is imported, the constructor runs it again, so it must take exactly what the class takes."""

import importlib
import inspect

import pytest

from hybrid_sysid.model.arguments import TORCH_FREE


@pytest.mark.parametrize("target", sorted(TORCH_FREE))
def test_each_part_has_its_class_signature(target):
    module, name = target.rsplit(".", 1)
    cls = getattr(importlib.import_module(module), name)
    part, window_bounds = TORCH_FREE[target]
    assert list(inspect.signature(cls).parameters.values()) == list(inspect.signature(part).parameters.values())
    if window_bounds is not None:  # the class's own bounds are the part's
        assert cls.window_bounds is window_bounds
