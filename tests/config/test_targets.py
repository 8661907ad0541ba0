"""What a config may name by _target_: any class of this package's model or baselines that provides what its key
asks (the protocols of model/base.py), checked by name before anything outside the package is imported, and with
a one-line error naming what a class lacks."""

import pytest

from hybrid_sysid.config.targets import build, known_class
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.model.base import Baseline, Network, Objective, lacks, members


def test_the_interfaces_name_what_each_kind_provides():
    assert members(Network) == ["prior_arguments", "window_bounds", "output_bounds", "__call__"]
    assert members(Objective) == ["uses_labels", "fir", "outside_fir", "monitor", "__call__"]
    assert members(Baseline) == ["predict_split", "fit_seconds", "check_lengths", "estimate"]


@pytest.mark.parametrize(
    "key, target",
    [
        ("model.net", "hybrid_sysid.model.networks.FastCNN"),
        ("model.net", "hybrid_sysid.model.networks.PaperCNN"),
        ("objective", "hybrid_sysid.model.objectives.HybridObjective"),
        ("objective", "hybrid_sysid.model.objectives.CombinedObjective"),
        ("objective", "hybrid_sysid.model.objectives.LabelledObjective"),
        ("objective", "hybrid_sysid.model.cross_segment.CrossSegmentObjective"),
        ("baseline", "hybrid_sysid.baselines.LeastSquaresFit"),
    ],
)
def test_every_class_of_the_package_meets_its_interface(key, target):
    cls = known_class(target, key)
    assert not lacks(cls, {"model.net": Network, "objective": Objective, "baseline": Baseline}[key])


@pytest.mark.parametrize(
    "key, target, words",
    [
        # a class of the package that is not a network: named with what it lacks
        ("model.net", "hybrid_sysid.model.module.IdentificationModule", "a class with prior_arguments, window_bounds"),
        ("model.net", "hybrid_sysid.model.objectives.LabelledObjective", "a class with prior_arguments"),
        ("objective", "hybrid_sysid.model.networks.FastCNN", "a class with uses_labels, fir, outside_fir, monitor"),
        # names that are no class of the package: refused before anything is imported from elsewhere
        ("model.net", "os.system", "a class of hybrid_sysid.model"),
        ("model.net", "hybrid_sysid.model.networks.nn", "there is none of that name"),
        ("model.net", "hybrid_sysid.model.networks.torch", "there is none of that name"),
        ("model.net", "hybrid_sysid.model.no_such_module.Net", "a class of hybrid_sysid.model"),
        ("objective", "hybrid_sysid.model.objectives._Private", "a class of hybrid_sysid.model"),
        ("baseline", "hybrid_sysid.model.networks.FastCNN", "a class of hybrid_sysid.baselines"),
        ("logger.x", "hybrid_sysid.model.networks.FastCNN", "one of lightning.pytorch.loggers.CSVLogger"),
    ],
)
def test_anything_else_is_one_line_naming_the_key(key, target, words):
    with pytest.raises(ConfigError) as err:
        known_class(target, key)
    message = str(err.value)
    assert message.startswith(f"{key}._target_ = '{target}' is not allowed: ") and "\n" not in message
    assert words in message


def test_an_owners_error_is_placed_under_its_config_key():
    node = {"_target_": "hybrid_sysid.model.networks.FastCNN", "p_min": [1, 1], "p_max": [2, 2], "kernel_size": 4}
    with pytest.raises(ConfigError, match=r"^model\.net\.kernel_size = 4 is not allowed: an odd integer"):
        build(node, "model.net")
    with pytest.raises(ConfigError, match=r"^model\.net\.depth = 3 is not allowed: not an argument of FastCNN"):
        build({**node, "kernel_size": 3, "depth": 3}, "model.net")
