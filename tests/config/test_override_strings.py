"""core.overrides.parse_override, the one reading of an override string, against Hydra's own parser: the same
prefix, key (with its package) and value text for every form the package meets, and a reading of its own where
Hydra's parser refuses a string in isolation (a record's text must still be read)."""

import pytest
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import OverrideType
from hydra.errors import HydraException

from hybrid_sysid.core.overrides import Override, parse_override, parse_overrides
from hybrid_sysid.runs.rundir import RunDir

FORMS = [
    "seed=1",
    "model.optim.lr=0.01",
    "+data.extra=1",
    "++trainer.extra.a=2",
    "~objective",
    "~objective=hybrid",
    "~model.net.channels",
    "+model@extra=fast_cnn",
    "hydra/launcher=basic",
    "hydra.sweep.dir=outputs/x",
    "tags=",
    "+tags=",
    "tags=[a,b]",
    "objective=hybrid,labelled",
    "seed=range(0,3)",
    "noise.train_std=interval(0.0,0.1)",
    "car.c3=${car.c2}",
    "data.path='/a=b/c'",
    'data.path="q = r"',
    "trainer.max_steps= 20",
]
PREFIX = {OverrideType.CHANGE: "", OverrideType.ADD: "+", OverrideType.FORCE_ADD: "++", OverrideType.DEL: "~"}


@pytest.mark.parametrize("text", FORMS)
def test_each_form_reads_as_hydra_reads_it(text):
    hydra = OverridesParser.create().parse_override(text)
    ours = parse_override(text)
    assert ours.prefix == PREFIX[hydra.type] and ours.deletes == hydra.is_delete()
    assert ours.written_key == hydra.get_key_element()
    assert ours.key == (hydra.key_or_group if hydra.package is None else f"{hydra.key_or_group}@{hydra.package}")
    assert ours.group == hydra.key_or_group
    assert ours.value == (hydra.get_value_string() if "=" in text else None)


def test_strings_hydra_refuses_alone_still_read():
    """A value with a second "=" or a character outside Hydra's grammar: a record holds it as Hydra took it
    quoted from a shell (launch.overrides quotes such values)."""
    for text in ("x=a=b", "data.path=/tmp/ü"):
        with pytest.raises(HydraException):
            OverridesParser.create().parse_override(text)
    assert parse_override("x=a=b") == Override("", "x", "a=b")
    assert parse_override("+data.path=/tmp/ü") == Override("+", "data.path", "/tmp/ü")
    assert parse_overrides("seed=1") == [] and parse_overrides(("seed=1",)) == [Override("", "seed", "1")]


def test_a_run_directory_gives_its_overrides_parsed(tmp_path):
    run = RunDir(tmp_path)
    assert run.parsed_overrides() == []  # no .hydra/overrides.yaml
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra" / "overrides.yaml").write_text("- seed=3\n- ~logger\n- +model@extra=fast_cnn\n")
    assert run.parsed_overrides() == [
        Override("", "seed", "3"),
        Override("~", "logger", None),
        Override("+", "model@extra", "fast_cnn"),
    ]
