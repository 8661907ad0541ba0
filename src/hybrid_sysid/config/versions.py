"""The config schema's version and the keys each version added, in one table.

Every saved config carries the version it was written with (``schema_version``; a config saved before versions
existed has none: version 0). A key added since a config was saved is absent from it, and that run did what the
key's default does, so a reader fills it in (``upgraded``): such a run resumes, evaluates and compares as the same
run as one holding the default. A key of the config's own version that it lacks is a file cut short.
"""

from __future__ import annotations

from hybrid_sysid.physics.faults import section_defaults as fault_defaults

KEY = "schema_version"
VERSION = 1  # the version this package writes; one more with each row of ADDED that a change adds
# (version, dotted key, the default that does what a config saved before the key existed did)
ADDED = (
    (1, "noise.train_std_max", None),
    (1, "car.seat_hardening", 0.0),
    (1, "sensor.gain_spread", 0.0),
    (1, "sensor.skew_max", 0.0),
    (1, "sensor.lowpass_hz", None),
    (1, "sensor.lowpass_range_hz", None),
    (1, "transfer.anchored_objectives", []),
    (1, "trainer.num_nodes", 1),
    (1, "tags", []),
    (1, "data.path", None),
    (1, "data.labels", None),
    (1, "data.module", None),
)


def _outside_fix(flat: dict) -> str:
    """objective.fix of a cross_segment config saved before the key: its target had no fix. On clean recordings
    that is what today's ``${fault_fix:}`` gives; under a fault "none", which a config composed today is not."""
    clean = all(flat.get(key, default) == default for key, default in fault_defaults().items())
    return "${fault_fix:}" if clean else "none"


# Keys an option of a config group gained (a group's option is not a section of the schema, so it has no version):
# (dotted key, the default that does what a config saved before it did, or a function of the flattened config
# giving it, and the option's _target_ under the key's parent). Filled in where a config holds that option.
OPTION_ADDED = (
    ("model.net.partner", False, "hybrid_sysid.model.anchored.AnchoredCNN"),
    ("objective.fix", _outside_fix, "hybrid_sysid.model.cross_segment.CrossSegmentObjective"),
)


def version_of(flat: dict) -> int:
    """The schema version of a flattened saved config: 0 when it has none (or one that is no whole number)."""
    version = flat.get(KEY, 0)
    return version if isinstance(version, int) and not isinstance(version, bool) and version >= 0 else 0


def added_since(version: int) -> dict:
    """{dotted key: default} of the keys added after ``version``, and of each registered fault's setting the table
    does not list (a fault added since, the package's or an installed one: a config without it ran without it, as
    its default, off, does), so adding a fault adds no row here."""
    listed = {key for _, key, _ in ADDED}
    faults = {key: default for key, default in fault_defaults().items() if key not in listed}
    return {**faults, **{key: default for since, key, default in ADDED if since > version}}


def upgraded(flat: dict) -> dict:
    """A flattened saved config as this version reads it: the keys added since its version that it lacks, at
    their defaults, and this version's number (a config of a newer version keeps its own). A key whose section
    the config sets to null (``transfer: null``) is not added: the section holds no keys."""
    version = version_of(flat)
    added = {k: v for k, v in added_since(version).items() if not _in_null_section(flat, k)}
    for key, default, target in OPTION_ADDED:
        if key not in flat and flat.get(key.rsplit(".", 1)[0] + "._target_") == target:
            added[key] = default(flat) if callable(default) else default
    return {**added, **flat, KEY: max(version, VERSION)}


def _in_null_section(flat: dict, key: str) -> bool:
    parts = key.split(".")
    return any(".".join(parts[:i]) in flat for i in range(1, len(parts)))
