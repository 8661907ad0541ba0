"""Recording faults and model mismatches, one file each (docs/faults.md): the sensors' gain, skew and low-pass, and
the hardening seat spring. Each declares its settings, its draw per recording, how it acts on the signals and its
classical fix (``base.Fault``); the registry hands them to the simulator, the cache key, the checks, the config
schema and the docs table. Plain numpy."""

from hybrid_sysid.physics.faults.base import Fault, Setting, value_of
from hybrid_sysid.physics.faults.chain import FaultDraws, SensorFaults, apply
from hybrid_sysid.physics.faults.fix import FaultProblem, Fix, lstsq_columns
from hybrid_sysid.physics.faults.gain import Gain
from hybrid_sysid.physics.faults.hardening import Hardening
from hybrid_sysid.physics.faults.lowpass import Lowpass
from hybrid_sysid.physics.faults.registry import (
    GROUP,
    fault,
    fix_code,
    fix_for,
    fixes,
    register,
    register_installed,
    registered,
    section_defaults,
    settings,
    table,
    unregister,
)
from hybrid_sysid.physics.faults.skew import Skew

# the registration order is the order each recording draws them: the first three as before the registry, so the
# same seed gives the same faults
for _builtin in (Gain, Skew, Lowpass, Hardening):
    register(_builtin)

__all__ = [
    "GROUP",
    "Fault",
    "FaultDraws",
    "FaultProblem",
    "Fix",
    "SensorFaults",
    "Setting",
    "apply",
    "fault",
    "fix_code",
    "fix_for",
    "fixes",
    "lstsq_columns",
    "register",
    "register_installed",
    "registered",
    "section_defaults",
    "settings",
    "table",
    "unregister",
    "value_of",
]
