"""The classes a config may name by ``_target_``: this package's networks, objectives and baselines, and
Lightning's loggers and callbacks. Nothing else is ever imported or called from a config.

A run directory is data a user may have received from someone else (its .hydra/config.yaml is read by
hybrid-sysid-eval, hybrid-sysid-predict, load_estimator, init_from and resume=), so a ``_target_`` is looked up
here by name before anything is imported: any other name is a one-line ConfigError naming the key. Arguments
are plain values; a nested ``_target_`` (an argument that would build another object) is refused the same way.
"""

from __future__ import annotations

import importlib

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.core.checks import ConfigError, format_value

_NETWORKS = ("FastCNN", "PaperCNN")
_OBJECTIVES = ("LabelledObjective", "HybridObjective", "CombinedObjective")
_LOGGERS = ("CSVLogger", "TensorBoardLogger", "MLFlowLogger")
_CALLBACKS = ("EarlyStopping", "ModelSummary", "RichModelSummary", "RichProgressBar", "TQDMProgressBar")
# config key -> {the _target_ a config may give: (module, class name)}
KNOWN: dict[str, dict[str, tuple[str, str]]] = {
    "model.net": {f"hybrid_sysid.model.networks.{n}": ("hybrid_sysid.model.networks", n) for n in _NETWORKS},
    "objective": {f"hybrid_sysid.model.objectives.{n}": ("hybrid_sysid.model.objectives", n) for n in _OBJECTIVES},
    "baseline": {"hybrid_sysid.baselines.LeastSquaresFit": ("hybrid_sysid.baselines.least_squares", "LeastSquaresFit")},
    "logger": {f"lightning.pytorch.loggers.{n}": ("lightning.pytorch.loggers", n) for n in _LOGGERS},
    "callbacks": {f"lightning.pytorch.callbacks.{n}": ("lightning.pytorch.callbacks", n) for n in _CALLBACKS},
}
FAMILIES = ("logger", "callbacks")  # a mapping of names, each to a _target_: logger.<name>, callbacks.<name>


def _family(key: str) -> str:
    """logger.<name> -> logger, callbacks.<name> -> callbacks; model.net, objective and baseline are their own."""
    return next((f for f in FAMILIES if key.startswith(f + ".")), key)


def check_target(target, key: str) -> None:
    """ConfigError unless ``target`` is one of KNOWN for ``key``; imports nothing."""
    allowed = KNOWN[_family(key)]
    if not isinstance(target, str) or target not in allowed:
        raise ConfigError(
            f"{key}._target_ = {format_value(target)} is not allowed: one of "
            f"{', '.join(sorted(allowed))} (a config names only this package's classes)"
        )


def known_class(target, key: str) -> type:
    """The class a ``_target_`` at ``key`` names, imported only when it is one of KNOWN; ConfigError otherwise."""
    check_target(target, key)
    module, name = KNOWN[_family(key)][target]
    return getattr(importlib.import_module(module), name)


def arguments(node, key: str) -> tuple[type, dict]:
    """The class and the plain keyword arguments of the node at ``key`` ({_target_, arguments...})."""
    spec = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else dict(node or {})
    if not isinstance(spec, dict):
        raise ConfigError(f"{key} = {format_value(spec)} is not allowed: a mapping with a _target_")
    target = spec.pop("_target_", None)
    _no_targets_in(spec, key)  # before anything is imported
    cls = known_class(target, key)
    unknown = sorted(k for k in spec if isinstance(k, str) and k.startswith("_"))
    if unknown:
        raise ConfigError(f"{key}.{unknown[0]} is not allowed: {key} takes its class's own arguments")
    return cls, spec


def build(node, key: str, **extra):
    """The object the node at ``key`` describes, built by its own constructor (whose checks name their
    argument); ``extra`` keyword arguments replace the node's."""
    cls, kwargs = arguments(node, key)
    return cls(**{**kwargs, **extra})


def _no_targets_in(value, key: str) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            if k == "_target_":
                raise ConfigError(
                    f"{key}._target_ = {format_value(v)} is not allowed inside an argument: arguments are plain values"
                )
            _no_targets_in(v, f"{key}.{k}")
    elif isinstance(value, list):
        for v in value:
            _no_targets_in(v, key)
