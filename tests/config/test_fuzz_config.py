"""Every key of the composed config, and every group's choice, given hostile values: each is accepted, or refused
by one ConfigError whose line names the key. Never another exception, which the command would print as "the checks
could not complete" without the key. Driven in this process through the checks the command runs before it makes
any directory (TrainPreflight.check, and the one-line composition error); tests/cli/test_bad_values.py runs the
command itself on the cases of issue 46. hypothesis draws further values, derandomized so CI sees the same ones."""

import copy
import math
from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf, open_dict
from omegaconf.errors import OmegaConfBaseException

from hybrid_sysid.config import CONF_DIR, flatten
from hybrid_sysid.config.composition import composition_error
from hybrid_sysid.core.checks import ConfigError

HOSTILE = [0, -1, -7.5, 1e300, -1e300, math.nan, math.inf, -math.inf, "", " ", "abc", 10**30, 2**63, -(2**70)]
GROUPS = sorted(p.name for p in Path(CONF_DIR).iterdir() if p.is_dir() and not p.name.startswith("_"))
hostile_values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**80), max_value=2**80),
    st.text(max_size=8),
    st.sampled_from(HOSTILE),
)


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cache = tmp_path_factory.mktemp("cache")
        return compose(config_name="config", overrides=["data=tiny", f"data.cache_dir={cache}"])


KEYS = None


def default_keys() -> list[str]:
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config")
    return sorted(flatten(OmegaConf.to_container(cfg, resolve=False)))


def names(line: str, key: str) -> bool:
    """The line names the key: its dotted path, or (a check of two keys' relation, or of a list's item) its last
    part as the owner's argument."""
    last = key.rsplit(".", 1)[-1]
    return key in line or f"{last} " in line or f"{last}=" in line or f"{last}:" in line or f"{last}," in line


def outcome(cfg, key: str, value) -> str | None:
    """None when the command would go on; else the line it would print."""
    from hybrid_sysid.cli.train import TrainPreflight

    cfg = copy.deepcopy(cfg)
    try:
        with open_dict(cfg):
            OmegaConf.update(cfg, key, value, merge=True)
    except OmegaConfBaseException as exc:  # what composition refuses on the command line
        wrapped = ConfigCompositionException(f"Error merging override {key}={value}")
        wrapped.__cause__ = exc
        return str(composition_error(wrapped))
    try:
        TrainPreflight().check(cfg, [])
    except ConfigError as exc:
        return str(exc)
    return None


def check(cfg, key, value):
    line = outcome(cfg, key, value)
    if line is not None:
        assert "\n" not in line and names(line, key), (key, value, line)


@pytest.mark.parametrize("key", default_keys())
def test_every_key_with_every_hostile_value_is_accepted_or_named(base, key):
    for value in HOSTILE:
        check(base, key, value)


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(key=st.sampled_from(default_keys()), value=hostile_values)
def test_drawn_values_of_any_key_are_accepted_or_named(base, key, value):
    check(base, key, value)


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(group=st.sampled_from(GROUPS), choice=st.one_of(st.text(max_size=10), st.sampled_from(["nonexistent", ""])))
def test_unknown_choices_of_every_group_are_one_line_naming_the_group(group, choice):
    options = {p.stem for p in (Path(CONF_DIR) / group).glob("*.yaml")}
    if choice in options:
        return
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        try:
            compose(config_name="config", overrides=[f"{group}={choice}"])
        except Exception as exc:  # noqa: BLE001 - a parse error or a missing option: both must be named
            error = composition_error(exc)
            assert error is not None and error.key == group, (group, choice, exc)
            assert "\n" not in str(error)


@pytest.mark.parametrize(
    "key, value",
    [
        ("noise.train_std", 1e300),
        ("trainer.threads", 100000),
        ("trainer.devices", 0),
        ("trainer.extra.max_epochs", -5),
        ("car.seat_hardening", 1e30),
        ("paths.root", ""),
        ("model.net._target_", "hybrid_sysid.model.networks.nn.Module"),
        ("model.net.n_layers", 10**30),
        ("car.c2", 1e300),
    ],
)
def test_the_cases_of_issue_46_are_refused_naming_the_key(base, key, value):
    line = outcome(base, key, value)
    assert line is not None and line.startswith(f"{key} = "), line


def test_hostile_values_inside_a_received_saved_config_are_one_line_naming_the_key(base, tmp_path):
    """hybrid-sysid-eval (and init_from=) read a run's .hydra/config.yaml: a hostile value there is one line too."""
    from hybrid_sysid.cli.evaluate import evaluation_config, validate_saved

    saved = OmegaConf.to_container(base, resolve=False)
    for key, value in [
        ("noise.train_std", 1e300),
        ("trainer.threads", 10**30),
        ("model.net.n_layers", "abc"),
        ("car.seat_hardening", math.inf),
        ("model.optim.lr", 1e300),
        ("data.window", -1),
    ]:
        run = tmp_path / key
        (run / ".hydra").mkdir(parents=True)
        cfg = copy.deepcopy(saved)
        node = cfg
        *parents, last = key.split(".")
        for part in parents:
            node = node[part]
        node[last] = value
        (run / ".hydra" / "config.yaml").write_text(yaml.safe_dump(cfg))
        with pytest.raises(ConfigError) as err:
            validate_saved(evaluation_config(run, base, []), run)
        assert "\n" not in str(err.value) and (key in str(err.value) or names(str(err.value), key)), str(err.value)
