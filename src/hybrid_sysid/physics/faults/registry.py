"""The registry of faults: every fault the simulator, the cache key, the checks, the config schema, the classical
fixes (their names and their code) and the docs table know of, in the order they were registered (the order each
recording draws them).

The package's own register in ``physics.faults``; an installed package's, through an entry point of the group
``hybrid_sysid.faults`` whose value names its Fault subclass, at the registry's first reading (installing a package
is the act of trust, as for any plugin: docs/extending.md). ``register`` adds one in a process of one's own (a
notebook, a test) before the config schema is made (``hybrid_sysid.config``), whose ``sensor`` section lists the
settings then registered.
"""

from __future__ import annotations

from importlib.metadata import entry_points

from hybrid_sysid.core.checks import ConfigError, check_choice
from hybrid_sysid.physics.faults.base import Fault, Setting
from hybrid_sysid.physics.faults.fix import Fix

GROUP = "hybrid_sysid.faults"  # the entry point group of installed packages' faults
_FAULTS: dict[str, Fault] = {}
_installed: list[bool] = []  # non-empty once register_installed has run


def register(fault):
    """Register a Fault subclass (or instance) under its ``name``; returns what it was given, so it serves as a
    class decorator. A name or a config key already registered is refused: a fault is declared once."""
    instance = fault() if isinstance(fault, type) else fault
    if not isinstance(instance, Fault) or not instance.name or not instance.settings:
        raise TypeError(f"{fault!r}: a Fault subclass with a name and at least one Setting")
    if len({s.section for s in instance.settings}) != 1:
        raise TypeError(f"fault {instance.name!r}: its settings lie in one config section")
    taken = {s.key: f.name for f in _FAULTS.values() for s in f.settings}
    clash = [s.key for s in instance.settings if s.key in taken]
    if instance.name in _FAULTS or clash:
        what = f"the config key {clash[0]} of fault {taken[clash[0]]!r}" if clash else "a fault's name"
        raise ValueError(f"fault {instance.name!r}: {what} is registered already")
    _check_fix(instance)
    _FAULTS[instance.name] = instance
    return fault


def _check_fix(instance: Fault) -> None:
    """A fault's own fix is a Fix named as its ``fix`` and not yet registered; a fix it takes is registered."""
    own, named = instance.fix_code, [f.fix_code.name for f in _FAULTS.values() if f.fix_code is not None]
    if own is not None and (not isinstance(own, Fix) or own.name != instance.fix or own.name in named + ["none"]):
        raise TypeError(f"fault {instance.name!r}: fix_code a Fix named as its fix, {instance.fix!r}, and new")
    if own is None and instance.fix not in ["none", *named]:
        raise TypeError(f"fault {instance.name!r}: fix {instance.fix!r} is no registered fault's fix_code")


def unregister(name: str) -> None:
    """Take a fault out again (a test's own fault, at its end)."""
    _FAULTS.pop(name)


def register_installed() -> None:
    """Register the faults installed packages declare (GROUP) that are not yet; an import that raises is a
    one-line ConfigError naming the entry point. ``registered`` runs it once, at the registry's first reading."""
    _installed.append(True)
    for ep in entry_points(group=GROUP):
        try:
            fault = ep.load()
        except Exception as exc:  # noqa: BLE001 - a plugin's import may raise anything: one line names it
            why = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
            raise ConfigError(
                f"entry point {GROUP}:{ep.name}", ep.value, f"a fault whose import works ({why})"
            ) from exc
        if not any(type(f) is fault or f is fault for f in _FAULTS.values()):
            register(fault)


def registered(section: str | None = None) -> list[Fault]:
    """The registered faults, in registration order; ``section``: those whose settings lie there."""
    if not _installed:
        register_installed()
    return [f for f in _FAULTS.values() if section is None or f.settings[0].section == section]


def settings(section: str | None = None) -> dict[str, Setting]:
    """{name: Setting} of the registered faults' settings (of one section, or {key: Setting} of all)."""
    return {(s.name if section else s.key): s for f in registered(section) for s in f.settings}


def fault(name: str) -> Fault:
    return {f.name: f for f in registered()}[name]


def fix_for(sensor, car) -> str:
    """The classical fix (``fixes``) of the faults a config simulates: that of the active fault of the
    lowest ``fix_rank``; "none" with none on. ``sensor``, ``car``: the sections, as objects or mappings."""
    on = [f for f in registered() if f.active(car if f.settings[0].section == "car" else sensor)]
    return min(on, key=lambda f: f.fix_rank).fix if on else "none"


def fixes() -> tuple[str, ...]:
    """The fixes a fit may take (baseline.fix): "none", then each registered fault's own, in registration order."""
    return ("none", *(f.fix_code.name for f in registered() if f.fix_code is not None))


def fix_code(name: str, key: str = "fix") -> Fix | None:
    """The code of the fix ``name`` (None for "none"); a one-line ConfigError naming ``key`` for one not registered."""
    check_choice(key, name, fixes())
    return next((f.fix_code for f in registered() if f.fix_code is not None and f.fix_code.name == name), None)


def _cell(value) -> str:
    return "null" if value is None else f"{value:g}" if isinstance(value, float) else str(value)


def table(faults=None) -> str:
    """The docs table of the faults' settings (docs/faults.md), one row per setting."""
    rows = [
        "| key | physical meaning | unit | default | drawn per recording | preset | fix |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for f in registered() if faults is None else faults:
        for s in f.settings:
            cells = [f"`{s.key}`", s.meaning, s.unit, f"`{_cell(s.default)}`", s.drawn, s.preset, f"`{f.fix}`"]
            rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def section_defaults() -> dict[str, object]:
    """{config key: default} of every registered setting: what a run saved before the fault existed ran."""
    return {s.key: s.default for s in settings().values()}
