"""A config that does not compose, in one line naming its key: an unknown group option, a value of the wrong type,
an unknown key, an override that does not parse. Hydra prints these in up to 16 lines (the options, the search
path, OmegaConf's object types); a refusal everywhere else in the project is one line, ``key = value is not
allowed: what is allowed``, so these are too."""

from __future__ import annotations

import re
import sys

from hydra.errors import ConfigCompositionException, MissingConfigException, OverrideParseException
from omegaconf.errors import OmegaConfBaseException

from hybrid_sysid.core.checks import NO_VALUE, ConfigError, Shown
from hybrid_sysid.core.overrides import parse_override


def composition_error(exc: BaseException) -> ConfigError | None:
    """The ConfigError that says what ``exc``, raised while Hydra composed the config, says; None for an exception
    that is not a composition's (a job's own, which keeps its record and its traceback)."""
    if isinstance(exc, MissingConfigException):
        return _missing_option(exc)
    if isinstance(exc, OverrideParseException):
        key = str(exc.override).split("=", 1)[0].lstrip("+~") or str(exc.override)
        return ConfigError(key, allowed=f"an override that parses, key=value ({_words(exc.message)})")
    if isinstance(exc, ConfigCompositionException):
        cause = exc.__cause__
        if isinstance(cause, OmegaConfBaseException) and cause.full_key:
            value = cause.value if cause.value is not None else NO_VALUE
            # OmegaConf's message: its first line; the lines after it name the key again and its object types
            first = (str(cause.msg or cause).strip().splitlines() or [""])[0]
            return ConfigError(cause.full_key, value, _words(first) + _launcher_hint(cause.full_key))
        lines = [line for line in str(exc).splitlines() if line.strip()]
        full_key = re.search(r"full_key: (\S+)", str(exc))
        if full_key and len(lines) > 1:  # a preset's key the schema lacks: "In 'experiment/tuned': ... full_key: k"
            where = re.match(r"In '([^']+)'", lines[0])
            said = _words(lines[1]) + (f" (composing {where.group(1)})" if where else "")
            return ConfigError(full_key.group(1), allowed=said + _launcher_hint(full_key.group(1)))
        return ConfigError(_override_key(lines[0]) if lines else "the config", allowed=_words(" ".join(lines)))
    full_key = re.search(r"full_key: (\S+)", str(exc))
    if isinstance(exc, (AttributeError, TypeError)) and full_key:
        # 'baseline={a:1}': OmegaConf merges the dict into the schema's null section and fails inside, unwrapped
        key = full_key.group(1)
        return ConfigError(key, allowed=f"a value of the schema's type; set a section's keys one by one ({key}.x=...)")
    if isinstance(exc, ValueError) and str(exc).startswith("Config group override must be a string"):
        # baseline=null: Hydra takes null as no option at all, before composing, and names no group
        group = _null_group()
        return ConfigError(group, Shown("null"), f"one of the group's options; ~{group} drops its choice")
    if isinstance(exc, ValueError) and str(exc).startswith("Only one of --run, --multirun"):
        # hybrid-sysid -m ... --cfg job: Hydra refuses the pair before composing, with a bare ValueError
        return ConfigError("the command line", allowed=f"{_words(str(exc))} (drop -m to print the config)")
    return None


def _null_group() -> str:
    """The group the command line set to null (``baseline=null``), from the arguments Hydra read."""
    for arg in sys.argv[1:]:
        key, _, value = arg.partition("=")
        if value.strip().lower() in ("null", "none", "~") and "." not in key:
            return key.lstrip("+")
    return "a config group"


def _missing_option(exc: MissingConfigException) -> ConfigError:
    """``objective=nonexistent``: the group is the key, the value the option, its options what is allowed."""
    missing = str(exc.missing_cfg_file or "")
    group, _, option = missing.rpartition("/")
    options = sorted(exc.options or [])
    if not group or not options:  # no group's option (the primary config, a --config-name): Hydra's first line
        return ConfigError(missing or "the config", allowed=_words(str(exc).splitlines()[0]))
    return ConfigError(group.replace("/", "."), option, f"one of {', '.join(options)}")


def _override_key(line: str) -> str:
    """The key of "Could not override 'trainer.foo'." or "Error merging override data.dt=abc"."""
    for marker in ("override '", "override "):
        if marker in line:
            rest = line.split(marker, 1)[1]
            return parse_override(rest.split("'", 1)[0]).key.rstrip(".") or line
    return "the config"


def _words(text: str) -> str:
    return " ".join(str(text).split())


def _launcher_hint(key: str) -> str:
    """The way out of a key the launcher chosen lacks: a preset's (experiment=tuned) or the user's joblib n_jobs
    beside launcher=basic is the common case."""
    if not key.startswith("hydra.launcher."):
        return ""
    if key == "hydra.launcher.n_jobs":
        return "; n_jobs is launcher=joblib's: keep launcher=joblib, with hydra.launcher.n_jobs=1 for one job at a time"
    return "; the launcher chosen has no such key: choose the launcher it belongs to (conf/launcher), or leave it out"
