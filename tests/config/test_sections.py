"""Config sections generated from the class that owns their values: model.optim is OptimSettings' fields, so a
setting added there is a config key with its type and default, and nothing else spells it."""

import dataclasses
import typing

import pytest
from hydra.errors import ConfigCompositionException

from hybrid_sysid.config.schema import OptimConfig
from hybrid_sysid.model.optim import OptimSettings


def described(cls) -> dict:
    """Each field's type and default."""
    hints = typing.get_type_hints(cls)
    return {f.name: (hints[f.name], f.default) for f in dataclasses.fields(cls)}


def test_model_optim_has_the_fields_types_and_defaults_of_optim_settings(make_cfg):
    owner = described(OptimSettings)
    assert described(OptimConfig) == owner
    composed = make_cfg("data=tiny").model.optim
    assert sorted(composed) == sorted(owner)
    OptimSettings(**composed).validate()  # the composed section builds its owner as it is


def test_the_generated_section_takes_overrides_and_refuses_what_its_owner_lacks(make_cfg):
    assert make_cfg("data=tiny", "model.optim.lr=0.01").model.optim.lr == 0.01  # the owner is frozen, the section not
    with pytest.raises(ConfigCompositionException):
        make_cfg("data=tiny", "model.optim.momentum=0.9")  # no such field of OptimSettings
    with pytest.raises(ConfigCompositionException):
        make_cfg("data=tiny", "model.optim.lr=fast")  # OptimSettings.lr is a float
