"""The classes a config may name by ``_target_``: this package's networks, objectives, baselines and data modules
(any class of hybrid_sysid.model, .baselines or .data that provides what its key asks: model/base.py), the
classes that installed packages declare as plugins (entry points: config/plugins.py, docs/extending.md), and a
list of Lightning's loggers and callbacks. Nothing else is ever imported or called from a config.

A run directory is data a user may have received from someone else (its .hydra/config.yaml is read by
hybrid-sysid-eval, hybrid-sysid-predict, load_estimator, init_from and resume=), so a ``_target_`` is checked by
name before anything outside this package is imported: a name neither this package's nor declared by an installed
package's entry point is a one-line ConfigError naming the key. Installing a package is the act of trust; a run
made with a plugin records its package (``plugin_fields``), and opened where it is missing says what to install.
Arguments are plain values; a nested ``_target_`` (an argument that would build another object) is refused the
same way. A new network or objective of this package is one module of hybrid_sysid.model and one YAML file.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import math
import numbers

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import plugins
from hybrid_sysid.core.checks import ConfigError, bad
from hybrid_sysid.core.options import CALLBACKS, LOGGERS, MONITORS
from hybrid_sysid.model.arguments import TORCH_FREE
from hybrid_sysid.model.base import Baseline, DataModule, Network, Objective, lacks

# config key -> (the package whose classes it may name, what such a class must provide)
OWN = {
    "model.net": ("hybrid_sysid.model", Network),
    "objective": ("hybrid_sysid.model", Objective),
    "baseline": ("hybrid_sysid.baselines", Baseline),
    "data.module": ("hybrid_sysid.data", DataModule),
}
# config key -> the members of its protocol an object sets in its constructor: checked on the object once built
ON_INSTANCE = {"data.module": ("window", "dataset")}
# config key -> {the _target_ of a library's class a config may give: (module, class name)}
LIBRARY: dict[str, dict[str, tuple[str, str]]] = {
    "logger": {f"lightning.pytorch.loggers.{n}": ("lightning.pytorch.loggers", n) for n in LOGGERS},
    "callbacks": {f"lightning.pytorch.callbacks.{n}": ("lightning.pytorch.callbacks", n) for n in CALLBACKS},
}
FAMILIES = ("logger", "callbacks")  # a mapping of names, each to a _target_: logger.<name>, callbacks.<name>


def _family(key: str) -> str:
    """logger.<name> -> logger, callbacks.<name> -> callbacks; model.net, objective and baseline are their own."""
    return next((f for f in FAMILIES if key.startswith(f + ".")), key)


def check_target(target, key: str, recorded: dict | None = None) -> None:
    """ConfigError unless ``target`` may be named at ``key``: a class path in this package's own (OWN; the module
    must exist), one an installed package declares in the entry point group of ``key`` (config/plugins.py), or one
    of LIBRARY's names. Imports nothing outside this package. ``recorded``: what a run's record says of the plugin
    class at ``key``, so the refusal of one not installed names its package."""
    family = _family(key)
    if family in OWN:
        package = OWN[family][0]
        own = isinstance(target, str) and target.startswith(package + ".")
        if not own and plugins.declared(target, family) is not None:
            return
        parts = target.split(".") if isinstance(target, str) else []
        module = ".".join(parts[:-1])
        if not own:
            why = plugins.missing(target, family, recorded)
            bad(f"{key}._target_", target, f"a class of {package} or one an installed package declares; {why}")
        named = all(p.isidentifier() and not p.startswith("_") for p in parts)
        if not named or _find_module(module) is None:
            bad(f"{key}._target_", target, f"a class of {package} (a config names only this package's classes)")
        return
    allowed = LIBRARY[family]
    if not isinstance(target, str) or target not in allowed:
        bad(
            f"{key}._target_",
            target,
            f"one of {', '.join(sorted(allowed))} (a config names only this package's and these classes)",
        )


def _find_module(name: str):
    """The module spec of ``name``, None where there is none. A path through a module that is no package
    (hybrid_sysid.model.networks.nn, the torch.nn it imports) makes find_spec raise: that is no module either."""
    try:
        return importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None


def known_class(target, key: str) -> type:
    """The class a ``_target_`` at ``key`` names, imported once check_target lets it, and holding every member of
    what its key asks (OWN: model/base.py); ConfigError otherwise. A plugin's module is imported here, and an
    exception it raises is one line naming its entry point."""
    check_target(target, key)
    family = _family(key)
    if family not in OWN:
        module, name = LIBRARY[family][target]
        return getattr(importlib.import_module(module), name)
    package, interface = OWN[family]
    plugin = None if target.startswith(package + ".") else plugins.declared(target, family)
    if plugin is not None:
        cls = plugins.load(plugin, key)
        source = f"{interface.__name__} of hybrid_sysid.model.base; the {plugins.describe(plugin)}"
        if not inspect.isclass(cls):
            bad(f"{key}._target_", target, f"a class ({source} names a {type(cls).__name__})")
    else:
        module, name = target.rsplit(".", 1)
        cls = getattr(importlib.import_module(module), name, None)
        if not (inspect.isclass(cls) and cls.__module__.startswith(package + ".")):
            bad(f"{key}._target_", target, f"a class of {package} (there is none of that name)")
        source = f"{interface.__name__}, model/base.py"
    missing = [m for m in lacks(cls, interface) if m not in ON_INSTANCE.get(family, ())]
    if missing:
        bad(f"{key}._target_", target, f"a class with {', '.join(missing)} ({source})")
    return cls


def built_classes(cfg: DictConfig) -> dict[str, str]:
    """Config key -> the ``_target_`` a run of ``cfg`` builds: its baseline's, else its network's and objective's
    (a baseline run keeps the unused default objective), and its data module's when data.module names one."""
    baseline = OmegaConf.select(cfg, "baseline", default=None, throw_on_resolution_failure=False)
    keys = ("baseline",) if baseline is not None else ("model.net", "objective")
    keys += ("data.module",)
    found = {}
    for key in keys:
        try:
            target = OmegaConf.select(cfg, f"{key}._target_", default=None, throw_on_resolution_failure=False)
        except Exception:  # noqa: BLE001 - a malformed node: the builder names it when it reads it
            continue
        if isinstance(target, str):
            found[key] = target
    return found


def plugin_fields(cfg: DictConfig) -> dict:
    """The record's ``plugins`` (config key -> the plugin class's entry point, package and version) when the run
    builds a class of another installed package; {} otherwise."""
    made = {k: plugins.record_of(t, k) for k, t in built_classes(cfg).items() if not t.startswith(OWN[k][0] + ".")}
    made = {k: v for k, v in made.items() if v is not None}
    return {"plugins": made} if made else {}


def check_saved(cfg: DictConfig, record) -> None:
    """A run's saved config names only classes that may be named here: a plugin class whose package is not
    installed is a ConfigError naming the package its record says the run was made with."""
    recorded = record.get("plugins") if isinstance(record, dict) else None
    recorded = recorded if isinstance(recorded, dict) else {}
    for key, target in built_classes(cfg).items():
        check_target(target, key, recorded.get(key))


def arguments(node, key: str) -> tuple[type, dict]:
    """The class and the plain keyword arguments of the node at ``key`` ({_target_, arguments...})."""
    spec = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else dict(node or {})
    if not isinstance(spec, dict):
        bad(key, spec, "a mapping with a _target_")
    target = spec.pop("_target_", None)
    _no_targets_in(spec, key)  # before anything is imported
    cls = known_class(target, key)
    unknown = sorted(k for k in spec if isinstance(k, str) and k.startswith("_"))
    if unknown:
        bad(f"{key}.{unknown[0]}", spec[unknown[0]], f"{key} takes its class's own arguments")
    return cls, spec


def build(node, key: str, **extra):
    """The object the node at ``key`` describes, built by its own constructor, whose checks name their argument:
    a ConfigError places that argument under ``key`` (``model.net`` + ``kernel_size``). An argument the
    constructor does not take is refused first, with what it takes (a run saved by an older version may name an
    argument since removed). ``extra`` keyword arguments replace the node's."""
    cls, kwargs = arguments(node, key)
    kwargs = {**kwargs, **extra}
    _check_arguments(cls, kwargs, key)
    try:
        built = cls(**kwargs)
    except ConfigError as exc:
        raise exc.under(key) from None
    family = _family(key)
    missing = lacks(built, OWN[family][1]) if family in ON_INSTANCE else []
    if missing:
        what = f"a class whose objects have {', '.join(missing)} ({OWN[family][1].__name__}, model/base.py)"
        bad(f"{key}._target_", node.get("_target_"), what)
    return built


def own_part(node, key: str):
    """For one of this package's own classes (model.arguments.TORCH_FREE), the torch-free part of its constructor run on
    the node's arguments before the class's module, and torch, is imported: (that part's result, the network's
    window bounds or None). None for any other class, whose constructor checks its arguments once built."""
    spec = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else dict(node or {})
    if not isinstance(spec, dict) or spec.get("_target_") not in TORCH_FREE:
        return None
    target = spec.pop("_target_")
    if any(isinstance(k, str) and k.startswith("_") for k in spec):  # arguments() names those
        return None
    _no_targets_in(spec, key)
    part, window_bounds = TORCH_FREE[target]
    _check_arguments(part, spec, key, target.rsplit(".", 1)[1])  # the part's signature is the class's
    try:
        return part(**spec), (None if window_bounds is None else window_bounds(**spec))
    except ConfigError as exc:
        raise exc.under(key) from None
    except Exception:  # noqa: BLE001 - a value of a type no check expects: the constructor, once built, names it
        return None


def _check_arguments(cls, kwargs: dict, key: str, name: str | None = None) -> None:
    """Every keyword a parameter of ``cls``'s constructor (unless it takes ``**kwargs``); ``name``: the class's,
    where ``cls`` is a function of the same signature."""
    try:
        params = inspect.signature(cls).parameters
    except (TypeError, ValueError):  # a signature Python cannot read: the constructor checks its own
        return
    if any(p.kind is p.VAR_KEYWORD for p in params.values()):
        return
    takes = [n for n, p in params.items() if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    for arg, value in kwargs.items():
        if arg not in takes:
            bad(f"{key}.{arg}", value, f"not an argument of {name or cls.__name__}, which takes {', '.join(takes)}")


def _no_targets_in(value, key: str) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            if k == "_target_":
                bad(f"{key}._target_", v, "no _target_ inside an argument: arguments are plain values")
            _no_targets_in(v, f"{key}.{k}")
    elif isinstance(value, list):
        for v in value:
            _no_targets_in(v, key)


def check_objective_members(objective, key: str) -> None:
    """The values of an objective's members (model/base.py's Objective) as the run reads them: a plugin's
    ``fir = 42`` would otherwise fail deep in the data module, far from the key that named the class."""
    if not isinstance(objective.uses_labels, bool):
        bad(f"{key}.uses_labels", objective.uses_labels, "True or False (Objective, model/base.py)")
    for name in ("fir", "outside_fir"):
        taps = getattr(objective, name)
        if taps is None:
            continue
        try:
            ok = len(taps) >= 1 and all(isinstance(t, numbers.Real) and math.isfinite(t) for t in taps)
        except TypeError:  # no length, or not iterable
            ok = False
        if not ok:
            bad(f"{key}.{name}", taps, "None, or the band-pass's taps: finite numbers (Objective, model/base.py)")
    if objective.monitor not in MONITORS[1:]:
        bad(f"{key}.monitor", objective.monitor, f"one of {', '.join(MONITORS[1:])} (Objective, model/base.py)")


def data_module(cfg: DictConfig, objective=None):
    """The data module ``data.module`` describes (a plugin's, say: docs/extending.md), built from its own arguments,
    which interpolate the run's values (``${data.window}``, ``${seed}``); None when it is null, the simulator's. Its
    constructor loads nothing, so the checks before any work build it too. ConfigError naming the key: a class
    that may not be named or lacks a member of DataModule (model/base.py), a constructor that refuses its arguments,
    a window or dt other than data.window or data.dt, a baseline run (a baseline reads the simulator's whole
    recordings), data.path set too, or an objective (``objective``, else the config's) that reads band-passed
    signals or an outside fit, which such batches do not carry."""
    key = "data.module"
    node = OmegaConf.select(cfg, key)
    if node is None:
        return None
    if cfg.get("baseline") is not None:
        bad(f"{key}._target_", node.get("_target_"), "none with baseline= (a baseline reads the simulated recordings)")
    if cfg.data.get("path") is not None:
        bad(f"{key}._target_", node.get("_target_"), "none with data.path (data=recordings reads its files itself)")
    if node.get("dt") is not None and node.get("dt") != cfg.data.dt:  # another step would misread the recordings
        bad(f"{key}.dt", node.get("dt"), f"the recordings' step, data.dt = {cfg.data.dt} (${{data.dt}})")
    objective = build(cfg.objective, "objective") if objective is None else objective
    for member, what in (("fir", "band-passed signals"), ("outside_fir", "fit over each window's outside samples")):
        if getattr(objective, member, None) is not None:
            why = f"an objective without {member}: the batches of {key} carry no {what}"
            bad("objective._target_", cfg.objective.get("_target_"), why)
    try:
        dm = build(node, key)
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - a plugin's constructor may raise anything: one line names it
        raise ConfigError(key, allowed=f"{type(exc).__name__}: {' '.join(str(exc).split())}") from exc
    if dm.window != cfg.data.window:
        bad(f"{key}.window", dm.window, f"data.window = {cfg.data.window}, the window the network is checked on")
    return dm
