"""The config schema's versions (config.versions): a saved config carries its version; reading it fills in the keys
added since at their defaults, while a key of its own version that it lacks marks a file cut short."""

import pytest
from omegaconf import OmegaConf

from hybrid_sysid.cli.evaluate import lacking
from hybrid_sysid.config import Config, ConfigError, flatten, validate
from hybrid_sysid.config.schema import SECTIONS
from hybrid_sysid.config.versions import ADDED, KEY, VERSION, upgraded
from hybrid_sysid.runs.resume import check_resume
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.runs.sweepdir import first_difference

TINY = ["data=tiny", "trainer=debug"]
ABSENT = object()


def plain(cfg) -> dict:
    return OmegaConf.to_container(cfg, resolve=False)


def saved(tmp_path, values: dict) -> RunDir:
    (tmp_path / ".hydra").mkdir(parents=True)
    OmegaConf.save(OmegaConf.create(values), tmp_path / ".hydra" / "config.yaml")
    return RunDir(tmp_path)


def without(values: dict, *keys) -> dict:
    """A copy of a plain config without the dotted keys."""
    out = OmegaConf.create(values)
    for key in keys:
        *path, last = key.split(".")
        node = OmegaConf.select(out, ".".join(path)) if path else out
        del node[last]
        if path and not node:  # a section added with its keys
            del (OmegaConf.select(out, ".".join(path[:-1])) if path[:-1] else out)[path[-1]]
    return plain(out)


def test_each_added_key_s_default_is_what_a_config_composed_now_holds(make_cfg):
    """The table's default is what makes a run saved before the key the same run as one of today: it must be
    the default a config composed now holds (its section's dataclass where the default config has no section)."""
    composed = make_cfg(*TINY)
    assert composed[KEY] == VERSION and all(since <= VERSION for since, _, _ in ADDED)
    for _, key, default in ADDED:
        value = OmegaConf.select(composed, key, default=ABSENT)
        if value is ABSENT:  # transfer: null by default
            head, rest = key.rsplit(".", 1)
            value = OmegaConf.structured(SECTIONS[head])[rest]
        assert plain(OmegaConf.create({"v": value}))["v"] == default, key


def test_a_config_saved_before_versions_compares_as_one_with_the_defaults_and_a_current_one_as_it_is(make_cfg):
    now = plain(make_cfg(*TINY))
    keys = [key for _, key, _ in ADDED if OmegaConf.select(OmegaConf.create(now), key, default=ABSENT) is not ABSENT]
    old = without(now, KEY, *keys)
    assert first_difference(old, now) is None
    assert upgraded(flatten(old)) == upgraded(flatten(now))
    cut = without(now, "car.seat_hardening")  # version 1, which has the key: the file lacks it
    assert first_difference(cut, now) == ("car.seat_hardening", "(absent)", 0.0)
    harder = {**now, "car": {**now["car"], "seat_hardening": 0.1}}  # another run than one saved before the key
    assert first_difference(without(now, KEY, "car.seat_hardening"), harder) == ("car.seat_hardening", 0.0, 0.1)
    merged = OmegaConf.merge(OmegaConf.structured(Config), OmegaConf.create(cut))
    assert lacking(OmegaConf.create(cut), merged) == ["car.seat_hardening"]
    merged_old = OmegaConf.merge(OmegaConf.structured(Config), OmegaConf.create(old))
    assert merged_old[KEY] == VERSION and lacking(OmegaConf.create(old), merged_old) == []


def test_resume_reads_an_unversioned_run_with_the_defaults_and_a_versioned_one_lacking_a_key_as_damaged(
    tmp_path, make_cfg
):
    now = plain(make_cfg(*TINY))
    old = saved(tmp_path / "old", without(now, KEY, "sensor", "car.seat_hardening"))
    check_resume(old, make_cfg(*TINY))
    with pytest.raises(ConfigError, match=r"another config \(car.seat_hardening = 0.0 there, 0.2 here\)"):
        check_resume(old, make_cfg(*TINY, "car.seat_hardening=0.2"))  # a key it lacks, at its default there
    cut = saved(tmp_path / "cut", without(now, "car.seat_hardening"))
    with pytest.raises(ConfigError, match=r"config.yaml is damaged: it lacks 1 keys \(car.seat_hardening\)"):
        check_resume(cut, make_cfg(*TINY))


def test_a_version_this_package_does_not_know_is_refused(make_cfg):
    validate(make_cfg(*TINY, f"{KEY}=0"), training=False)  # a run saved before versions, evaluated
    with pytest.raises(ConfigError, match=rf"^{KEY} = {VERSION + 1} is not allowed: a version of the config schema"):
        validate(make_cfg(*TINY, f"{KEY}={VERSION + 1}"), training=False)


@pytest.mark.parametrize(
    "option, key",
    [(["model=anchored"], "model.net.partner"), (["objective=cross_segment"], "objective.fix")],
)
def test_a_key_an_option_gained_reads_as_what_a_config_saved_before_it_did(make_cfg, option, key):
    """A group's option has no schema version: a config holding the option but not the key is filled in, a config
    of another option is left alone, and a cross_segment run under a fault had no fix, which today's is not."""
    now = plain(make_cfg(*TINY, *option))
    assert first_difference(without(now, key), now) is None
    other = plain(make_cfg(*TINY))
    assert key not in upgraded(flatten(other))
    if key == "objective.fix":
        faulted = plain(make_cfg(*TINY, *option, "fault=gain"))
        assert first_difference(without(faulted, key), faulted) == (key, "none", "${fault_fix:}")
