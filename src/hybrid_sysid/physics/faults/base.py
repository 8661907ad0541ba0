"""What a recording fault or model mismatch declares (docs/faults.md, "Adding a fault").

A fault is one subclass of ``Fault`` in one file: its settings (the config keys, their defaults, ranges and one-line
meaning), how each recording draws it, how it acts on the recorded seat and body channels, and its classical fix
(``fix``; its code, a ``physics.faults.fix.Fix``, in ``fix_code``).
The registry (``physics.faults.registry``) hands every fault to the simulator, the cache key, the checks, the config
schema and the docs table, so none of them names a fault. Plain numpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, List, Optional

import numpy as np

from hybrid_sysid.core.checks import check_number
from hybrid_sysid.physics.faults.fix import Fix


@dataclass(frozen=True)
class Setting:
    """One config key of a fault, ``<section>.<name>``; its default turns the fault off."""

    name: str
    default: Any  # a number, or None for a pair that is off
    meaning: str  # one line: the docs table's "physical meaning"
    unit: str = ""
    drawn: str = "nothing: fixed"  # what each recording draws from it (the docs table)
    preset: str = "none"  # the preset that sets it, with its value (the docs table)
    low: float | None = 0.0  # the allowed range of a number, checked by ``check``
    high: float | None = None
    high_open: bool = False
    allowed: str = ""  # the range's words in the error; empty: the unit
    pair: bool = False  # a list of two numbers, or null; its range is the fault's to check (``Fault.validate``)
    section: str = "sensor"
    # kept in every faulted dataset's key even at its default: the settings of the first faults, whose caches
    # were keyed so before the registry; a later fault's setting enters the key only when set, so registering a
    # fault leaves every other key as it was
    keyed_at_default: bool = False

    @property
    def key(self) -> str:
        return f"{self.section}.{self.name}"

    @property
    def type(self):
        """Its type in the config schema."""
        return Optional[List[float]] if self.pair else float

    def normalise(self, value):
        """A config's list as a tuple of floats: hashable, and [20, 40] keys as [20.0, 40.0]."""
        if self.pair and value is not None and not isinstance(value, (str, int, float)):
            try:
                return tuple(float(v) for v in value)
            except (TypeError, ValueError):
                return tuple(value)  # the fault's check names it
        return value

    def check(self, value) -> None:
        """A number within its declared range, ConfigError naming the key; a pair is its fault's to check."""
        if not self.pair:
            check_number(self.key, value, self.low, self.high, high_open=self.high_open, unit=self.allowed or self.unit)


def value_of(config, setting: Setting):
    """A setting's value in a section: an object with it as attribute, a mapping (a config node), or its default."""
    if hasattr(config, "get") and not hasattr(config, setting.name):
        value = config.get(setting.name, setting.default)
    else:
        value = getattr(config, setting.name, setting.default)
    return setting.normalise(value)


class Fault:
    """A recording fault or model mismatch. Subclasses set the class attributes and override what they do."""

    name: str = ""  # the registry's key, as in fault=<name>
    settings: tuple[Setting, ...] = ()
    fix: str = "none"  # the name of its classical fix (baseline.fix), what estimator=ls_fix / eiv_fix fit with p
    # the fix's code (physics.faults.fix) when this file defines it, named ``fix``; None when the fault takes
    # another's (the low-pass takes the skew's) or has none
    fix_code: Fix | None = None
    fix_rank: int = 100  # with several faults on, ``${fault_fix:}`` takes the fix of the lowest rank
    order: int = 100  # where it acts in a sensor's chain: lower first (low-pass 10, gain 20, skew 30)
    compiled: bool = False  # physics.compiled_sensors' kernel applies it; else the dataset applies ``apply``

    def active(self, config) -> bool:
        """On when any of its settings differs from its default."""
        return any(value_of(config, s) != s.default for s in self.settings)

    def validate(self, config, dt: float, window: int | None = None, measurement: str | None = None) -> None:
        """ConfigError naming ``<section>.<key>``: each number within its declared range. ``window``: the steps a
        network reads; ``measurement``: the data's (data.measurement). Override to check more, calling this."""
        for s in self.settings:
            s.check(value_of(config, s))

    def draw(self, config, n: int, rng: np.random.Generator):
        """Its draw for each of ``n`` recordings (arrays with n rows), or None. Draw the unit variates always,
        whether on or off, and scale them after: turning a fault on or off then leaves the others' draws."""
        return None

    def apply(self, seat: np.ndarray, body: np.ndarray, draw, dt: float, **context) -> tuple[np.ndarray, np.ndarray]:
        """The (seat, body) channels (n, T) float64 as this fault leaves them; ``context``: ``half_width``."""
        return seat, body

    def margin(self, config, dt: float) -> int:
        """Steps its ``apply`` reads past a recording's end (and before its start, as rest)."""
        return 0
