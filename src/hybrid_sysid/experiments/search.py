"""A hyperparameter search's space and sampler, shared by ``hparams_search=...`` (the study sweeper,
hybrid_sysid.launch.search) and ``experiment=tuned`` (hybrid_sysid.experiments.tuned).

The space is written in Hydra's sweep syntax and read by Hydra's own parser: ``choice(...)`` (or ``a,b,c``) is
categorical; ``interval(a, b)`` is a uniform float (Hydra reads its bounds as floats), log-uniform when tagged log.

The sampler is optuna's TPE, seeded per trial: trial n is asked with a sampler seeded from (seed, n), so what it
proposes depends only on the study's trials before it, not on how many asks this process made. A search that is
interrupted and resumed from its stored study therefore proposes what an uninterrupted one does.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np
import optuna
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import ChoiceSweep, IntervalSweep
from omegaconf import DictConfig, OmegaConf
from optuna.distributions import CategoricalDistribution, FloatDistribution

from hybrid_sysid.core.checks import bad, check_choice, check_int
from hybrid_sysid.core.options import DIRECTIONS

SYNTAX = "choice(...) or interval(a, b), optionally tag(log, interval(a, b))"
# TPE settings a config may give (the others take functions, which a config cannot hold)
SAMPLER_KEYS = (
    "seed",
    "n_startup_trials",
    "n_ei_candidates",
    "multivariate",
    "group",
    "constant_liar",
    "consider_prior",
    "prior_weight",
    "consider_magic_clip",
    "consider_endpoints",
    "warn_independent_sampling",
)


def _parse(key: str, spec, name: str):
    try:
        return OverridesParser.create().parse_override(f"{key}={spec}").value()
    except Exception as exc:  # noqa: BLE001 - Hydra's parser raises its own classes
        bad(name, spec, f"{SYNTAX} ({' '.join(str(exc).split())})")


def search_space(params, where: str = "hydra.sweeper") -> dict:
    """Optuna distributions for ``params`` ({key: Hydra sweep syntax}); ConfigError for another syntax."""
    space = {}
    for key, spec in (params or {}).items():
        name = f"{where}.params.{key}"
        value = _parse(key, spec, name)
        if isinstance(value, ChoiceSweep):
            space[key] = CategoricalDistribution(list(value.list))
        elif isinstance(value, IntervalSweep):
            space[key] = FloatDistribution(value.start, value.end, log="log" in value.tags)
        else:
            bad(name, spec, SYNTAX)
    return space


def check_search(cfg: DictConfig, params, n_trials, where: str = "hydra.sweeper", trials_key: str = "") -> dict:
    """A search's space and budget, checked before any trial: n_trials >= 1 (named ``trials_key``, by default
    ``where``'s); each parameter choice(...) or interval(a, b) with a < b (and a > 0 when tagged log), and every
    value it can take of the type of the config's own value at that key (a text choice for a float key would only
    fail inside a trial, and stop a study). Returns the space (``search_space``); ConfigError naming ``where``'s
    key otherwise."""
    check_int(trials_key or f"{where}.n_trials", n_trials, 1)
    for key, spec in (params or {}).items():
        name = f"{where}.params.{key}"
        value = _parse(key, spec, name)
        if isinstance(value, IntervalSweep):
            if not value.start < value.end:
                bad(name, spec, "interval(a, b) needs a < b")
            if "log" in value.tags and not value.start > 0:
                bad(name, spec, "a log interval needs bounds > 0")
            values = [value.start, value.end]
        elif isinstance(value, ChoiceSweep):
            values = list(value.list)
        else:
            bad(name, spec, SYNTAX)
        current = OmegaConf.select(cfg, key, default=None)
        if current is None:
            bad(name, spec, f"the config has no value at {key} to search")
        for v in values:
            number = isinstance(v, (int, float)) and not isinstance(v, bool)
            wanted = isinstance(current, (int, float)) and not isinstance(current, bool)
            if wanted != number or (
                isinstance(current, int) and not isinstance(current, bool) and isinstance(v, float)
            ):
                bad(
                    name,
                    spec,
                    f"{v!r} is not of the type of {key} ({type(current).__name__}, {current!r} in the config)",
                )
    return search_space(params, where)


def check_sampler(settings, where: str = "hydra.sweeper.sampler") -> dict:
    """The TPE sampler's settings as a dict; ConfigError for a key TPE does not take (or one holding a
    function) and for a seed that is not an integer."""
    settings = OmegaConf.to_container(settings) if isinstance(settings, DictConfig) else dict(settings or {})
    for key in settings:
        if key not in SAMPLER_KEYS:
            bad(f"{where}.{key}", settings[key], f"a setting of the TPE sampler: {', '.join(SAMPLER_KEYS)}")
    seed = settings.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        bad(f"{where}.seed", seed, "an integer >= 0, or null for an unseeded search")  # numpy's SeedSequence's
    return settings


def sampler_for(settings: dict, number: int):
    """The TPE sampler that asks trial ``number``: seeded from (seed, number) when the search is seeded."""
    settings = dict(settings)
    if settings.get("seed") is not None:
        settings["seed"] = int(np.random.SeedSequence([int(settings["seed"]), number]).generate_state(1)[0])
    known = inspect.signature(optuna.samplers.TPESampler).parameters
    return optuna.samplers.TPESampler(**{k: v for k, v in settings.items() if k in known})


@dataclass
class StudySettings:
    """A search's settings, checked: its space (the preset's params and the command line's sweeps), the
    command line's other overrides (every trial's job gets them), and the study's budget and sampler."""

    space: dict
    fixed: list
    sampler: dict
    n_trials: int
    n_jobs: int
    direction: str
    name: str
    storage: str | None


def study_settings(cfg: DictConfig, settings, arguments, where: str = "hydra.sweeper") -> StudySettings:
    """StudySettings from the sweeper's settings (``hydra.sweeper``) and the command line's overrides; a
    ConfigError naming the key for a bad value, before any trial."""
    params, fixed = dict(settings.get("params") or {}), []
    for override in OverridesParser.create().parse_overrides(list(arguments)):
        if override.is_sweep_override():  # a sweep on the command line is a dimension of the space
            # as written (Hydra cannot print a sweep back), parsed again by check_search like the preset's own
            params[override.get_key_element()] = override.get_value_string()
        else:
            fixed.append(override.input_line)
    space = check_search(cfg, params, settings.get("n_trials"), where)
    n_jobs = settings.get("n_jobs", 1)
    check_int(f"{where}.n_jobs", n_jobs, 1)
    check_choice(f"{where}.direction", settings.get("direction", "minimize"), DIRECTIONS)
    direction = settings.get("direction", "minimize")
    return StudySettings(
        space=space,
        fixed=fixed,
        sampler=check_sampler(settings.get("sampler"), f"{where}.sampler"),
        n_trials=int(settings.get("n_trials")),
        n_jobs=n_jobs,
        direction=direction,
        name=str(settings.get("study_name") or "search"),
        storage=settings.get("storage") or None,
    )
