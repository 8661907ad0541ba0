"""The sensor faults together: their settings (``SensorFaults``, the ``sensor.*`` config keys), each recording's
draws (``FaultDraws``) and the chain that puts them on the clean channels (``apply``), all of them read from the
registry, so a fault registered later is drawn, applied, checked and keyed like the first ones."""

from __future__ import annotations

from dataclasses import FrozenInstanceError

import numpy as np

from hybrid_sysid.physics.faults.registry import registered, settings

SECTION = "sensor"


class FaultDraws(dict):
    """Per recording, each sensor fault's draw by the fault's name (None: nothing to apply). ``gains`` (n, 2) seat
    then body, ``skews`` (n,) seconds, the body sensor's delay against the seat sensor, and ``cutoffs`` (n, 2) Hz,
    seat then body, or None: the draws of the faults the compiled kernel applies (physics.compiled_sensors)."""

    def __init__(self, gains=None, skews=None, cutoffs=None, **others):
        super().__init__(gain=gains, skew=skews, lowpass=cutoffs, **others)

    gains = property(lambda self: self["gain"])
    skews = property(lambda self: self["skew"])
    cutoffs = property(lambda self: self["lowpass"])

    def _replace(self, **changes) -> "FaultDraws":
        """A copy with some draws changed, by a fault's name or ``gains``, ``skews``, ``cutoffs``: the name it had as
        a NamedTuple, kept for its callers."""
        names = {"gains": "gain", "skews": "skew", "cutoffs": "lowpass"}
        out = FaultDraws()
        out.update(self)
        out.update({names.get(k, k): v for k, v in changes.items()})
        return out


def _make(values: dict) -> "SensorFaults":
    return SensorFaults(**values)


class SensorFaults:
    """The sensor faults' magnitudes: a value for each setting of each registered sensor fault, its default (off)
    unless given, read as attributes (``sensor.skew_max``). Frozen and hashable: a DatasetSpec field. Each
    recording draws its own values (``draw``)."""

    __slots__ = ("_values",)

    def __init__(self, **values):
        known = settings(SECTION)
        for name in values:
            if name not in known:
                raise TypeError(f"SensorFaults got an unexpected keyword argument {name!r}")
        object.__setattr__(self, "_values", {n: known[n].normalise(v) for n, v in values.items()})

    def __getattr__(self, name):
        setting = None if name.startswith("_") else settings(SECTION).get(name)
        if setting is None:
            raise AttributeError(f"'SensorFaults' object has no attribute {name!r}")
        return self._values.get(name, setting.default)

    def __setattr__(self, name, value):
        raise FrozenInstanceError(f"cannot assign to field {name!r}")

    def values(self) -> dict:
        """{name: value} of every registered sensor setting."""
        return {name: getattr(self, name) for name in settings(SECTION)}

    def changed(self) -> tuple:
        """((name, value), ...) of the settings given a value other than their default, sorted: what tells two
        SensorFaults apart (one made before a fault was registered equals one made after)."""
        known = settings(SECTION)
        return tuple(sorted((n, v) for n, v in self._values.items() if n not in known or v != known[n].default))

    def __eq__(self, other) -> bool:
        return isinstance(other, SensorFaults) and self.changed() == other.changed()

    def __hash__(self) -> int:
        return hash(self.changed())

    def __repr__(self) -> str:
        return "SensorFaults(" + ", ".join(f"{n}={v!r}" for n, v in self.changed()) + ")"

    def __reduce__(self):
        return _make, (dict(self._values),)

    def __deepcopy__(self, memo):
        return self  # frozen

    def replace(self, **changes) -> "SensorFaults":
        return SensorFaults(**{**self._values, **changes})

    @property
    def active(self) -> bool:
        return any(f.active(self) for f in registered(SECTION))

    @property
    def compiled(self) -> bool:
        """Whether the compiled kernel applies every fault that is on (physics.compiled_sensors)."""
        return all(f.compiled for f in registered(SECTION) if f.active(self))

    def validate(self, dt: float, window: int | None = None) -> None:
        """ConfigError naming ``sensor.<key>``; ``window``: the steps a network reads, which a skew must stay within."""
        for f in registered(SECTION):
            f.validate(self, dt, window)

    def draw(self, n: int, rng: np.random.Generator) -> FaultDraws:
        """Each recording's faults, in the order the faults were registered. Each draws its unit variates always
        and scales them after: turning one fault on or off leaves the others' draws as they were."""
        draws = FaultDraws()
        for f in registered(SECTION):
            draws[f.name] = f.draw(self, n, rng)
        return draws

    def margin(self, dt: float) -> int:
        """Steps past a recording's end (and rest before its start) the faults' chain reads."""
        return max((f.margin(self, dt) for f in registered(SECTION)), default=0)

    def key_values(self) -> dict | None:
        """What the dataset's cache key holds of the sensors: None with every fault off, else each setting kept at
        its default too (``Setting.keyed_at_default``) and each other one that is set."""
        if not self.active:
            return None
        values = self.values()
        known = settings(SECTION)
        return {n: v for n, v in values.items() if known[n].keyed_at_default or v != known[n].default}


def apply(seat: np.ndarray, body: np.ndarray, draws: FaultDraws, dt: float, half_width: int = 32):
    """The faulted (seat, body), each (n, T) float64: each drawn fault in its ``order`` (each sensor's own low-pass,
    then its gain, then the body channel's skew, then faults registered later), a fault drawn None left out."""
    seat, body = np.asarray(seat, dtype=np.float64), np.asarray(body, dtype=np.float64)
    for fault in sorted(registered(SECTION), key=lambda f: f.order):
        if draws.get(fault.name) is not None:
            seat, body = fault.apply(seat, body, draws[fault.name], dt, half_width=half_width)
    return seat, body
