"""Classes of other installed packages (plugins): a package declares each through a Python entry point in the group
of its kind (GROUPS), and a config names it by its class path in ``_target_``, as it names this package's own.

Installing the package is the act of trust. The entry points are read from the installed packages' metadata, so
a name no installed package declares is refused before anything is imported, and a declared class is imported
only when a config names it. An entry point's value is ``module:Class`` (or ``module.Class``); its class path,
``module.Class``, is what a ``_target_`` gives. A run records the entry point and package of each plugin class it
was made with (``record_of``), so the run opened where that package is missing can say what to install.

A package declares its configs in the group CONFIGS, the entry point's value naming the package that holds them
(``mylab = "mylab.conf"``): ``searchpath`` gives them to Hydra (src/hydra_plugins/hybrid_sysid_configs), so a
plugin's options are chosen like the project's own, without ``hydra.searchpath``.
"""

from __future__ import annotations

from importlib import import_module
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path

from hybrid_sysid.config.schema import CONF_DIR
from hybrid_sysid.core.checks import ConfigError

# config key -> the entry point group its plugin classes are declared in
GROUPS = {
    "model.net": "hybrid_sysid.networks",
    "objective": "hybrid_sysid.objectives",
    "baseline": "hybrid_sysid.baselines",
    "data.module": "hybrid_sysid.datasets",
}
CONFIGS = "hybrid_sysid.configs"  # the entry point group whose values name packages of configs


def class_path(ep: EntryPoint) -> str:
    """``module:Class`` and ``module.Class`` -> ``module.Class``: what a ``_target_`` names."""
    return f"{ep.module}.{ep.attr}" if ep.attr else ep.module


def declared(target, key: str) -> EntryPoint | None:
    """The installed entry point of ``key``'s group whose class path is ``target``, None when no package declares
    it. Reads metadata only: nothing is imported."""
    if not isinstance(target, str):
        return None
    return next((ep for ep in entry_points(group=GROUPS[key]) if class_path(ep) == target), None)


def package_of(ep: EntryPoint) -> tuple[str | None, str | None]:
    """(name, version) of the installed package that declares ``ep``; (None, None) when its metadata lacks them."""
    dist = getattr(ep, "dist", None)
    if dist is None:
        return None, None
    return dist.metadata["Name"], dist.version


def describe(ep: EntryPoint) -> str:
    """``entry point hybrid_sysid.objectives:counting of hybrid-sysid-example-plugin``."""
    name = package_of(ep)[0]
    return f"entry point {ep.group}:{ep.name}" + (f" of {name}" if name else "")


def load(ep: EntryPoint, key: str):
    """The object ``ep`` names, its module imported now; a ConfigError naming the entry point and the exception
    when the import (the plugin's own code) raises or the module lacks the name."""
    if ep.attr:
        module, attrs = ep.module, ep.attr.split(".")
    else:
        module, _, attr = ep.module.rpartition(".")
        attrs = [attr]
    try:
        obj = import_module(module)
        for attr in attrs:
            obj = getattr(obj, attr)
    except Exception as exc:  # noqa: BLE001 - a plugin's import may raise anything: one line names it
        why = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
        raise ConfigError(
            f"{key}._target_", class_path(ep), f"the class of the {describe(ep)}, whose import raises {why}"
        ) from exc
    return obj


def record_of(target: str, key: str) -> dict | None:
    """What a run records of the plugin class ``target`` at ``key``: its class, entry point, package and version;
    None when no installed package declares it."""
    ep = declared(target, key)
    if ep is None:
        return None
    name, version = package_of(ep)
    return {"class": target, "entry_point": f"{ep.group}:{ep.name}", "package": name, "version": version}


def missing(target: str, key: str, recorded: dict | None) -> str:
    """What a refusal of ``target``, declared by no installed package, says to install: the package a run recorded
    (``recorded``: the run's record of it), else a package that declares it in ``key``'s group."""
    if isinstance(recorded, dict) and recorded.get("class") == target and recorded.get("package"):
        version = f" {recorded['version']}" if recorded.get("version") else ""
        return (
            f"the run was made with the entry point {recorded.get('entry_point')} of the package "
            f"{recorded['package']}{version}, not installed here: pip install {recorded['package']}"
        )
    return f"none declares it in the entry point group {GROUPS[key]} (docs/extending.md)"


def config_packages() -> dict[str, str]:
    """{package of configs: the name of the installed package that declares it} for each value of the group
    CONFIGS that is a dotted module name. Reads metadata only: nothing is imported (Hydra imports the package
    when it lists or reads its configs)."""
    found = {}
    for ep in entry_points(group=CONFIGS):
        name = ep.value.strip()
        if all(part.isidentifier() for part in name.split(".")):
            found.setdefault(name, package_of(ep)[0] or ep.name)
    return found


def is_own(path: str) -> bool:
    """Whether a Hydra search path element holds this package's own configs: its conf/ folder, or the package."""
    if path == "pkg://hybrid_sysid.conf":
        return True
    if "://" in path and not path.startswith("file://"):
        return False
    return Path(path.removeprefix("file://")).resolve() == Path(CONF_DIR).resolve()


def searchpath(paths: list[str]) -> list[tuple[str, str]]:
    """(provider, ``pkg://<package>``) to append to a Hydra search path of ``paths``: each installed package's
    configs (config_packages) when the search path holds this package's own, none for another Hydra app's, so
    that app never sees hybrid-sysid's plugins."""
    if not any(is_own(p) for p in paths):
        return []
    return [(f"hybrid-sysid plugin {who}", f"pkg://{name}") for name, who in config_packages().items()]
