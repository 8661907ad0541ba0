"""The key=value arguments of the commands that are not Hydra apps (hybrid-sysid-report, hybrid-sysid-predict),
parsed by one set of rules: key=value without dashes, as Hydra's overrides; each key known, given once unless it
repeats, converted and checked; a bad argument is one UsageError naming the key, the value and what is allowed."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hybrid_sysid.core.checks import ConfigError, check_dt


class UsageError(ConfigError):
    """A bad argument: one line on stderr, exit status 2."""


@dataclass(frozen=True)
class Key:
    """One key a command takes. ``kind``: text, bool (true or false), int (>= ``low``, or by ``check``), dt (a time
    step in seconds, core.checks.check_dt), choice (one of ``choices``) or list (comma-separated, brackets optional).
    ``repeats``: may be given more than once, each value kept in order."""

    kind: str = "text"
    default: object = None
    choices: tuple = ()
    low: int = 1
    check: Callable | None = None  # int: the check of the value's owner, in place of low (windows: inference's)
    repeats: bool = False
    allowed: str = ""  # what the key takes, in the error's words; derived from the kind when empty


def parse(argv: list[str], keys: dict[str, Key], positional: bool = False) -> tuple[dict, list[str]]:
    """({key: value} with every key's default, the positional arguments). With ``positional``, an argument
    without "=" is one, and so is one whose key is unknown but which names an existing path (a directory called
    key=value)."""
    values = {name: ([] if key.repeats else key.default) for name, key in keys.items()}
    given, rest = set(), []
    for arg in argv:
        key, sep, value = arg.partition("=")
        if arg.startswith("-"):
            hint = arg.lstrip("-") if sep else f"{arg.lstrip('-')}=VALUE"
            raise UsageError(arg, allowed=f"key=value without dashes ({hint}); see --help")
        if not sep or (key not in keys and positional and (not key.isidentifier() or Path(arg).exists())):
            if not positional:
                raise UsageError(arg, allowed=f"key=value, a key one of {', '.join(keys)}")
            rest.append(arg)
            continue
        if key not in keys:
            raise UsageError(key, allowed=f"a key one of {', '.join(keys)} (in {arg!r})")
        if key in given and not keys[key].repeats:
            raise UsageError(key, allowed=f"once (it is given twice; the second time as {arg!r})")
        given.add(key)
        converted = convert(key, value, keys[key])
        if keys[key].repeats:
            values[key].append(converted)
        else:
            values[key] = converted
    return values, rest


def convert(name: str, value: str, key: Key):
    """The value of one argument as its kind has it; UsageError otherwise."""
    if not value:
        raise UsageError(name, value, key.allowed or "a value: key=VALUE")
    if key.kind == "bool":
        if value.lower() not in ("true", "false"):
            raise UsageError(name, value, "true or false")
        return value.lower() == "true"
    if key.kind == "int":
        try:
            number = int(value)
        except ValueError:
            number = key.low - 1 if key.check is None else value
        if key.check is not None:  # the owner's range, shown with the value as given
            try:
                return key.check(number)
            except ConfigError as exc:
                raise UsageError(name, value, exc.allowed) from None
        if number < key.low:
            raise UsageError(name, value, key.allowed or f"an integer >= {key.low}")
        return number
    if key.kind == "dt":
        return check_dt(value, name, key.allowed or "a time step > 0 in seconds", UsageError, text=True)
    if key.kind == "choice":
        if value not in key.choices:
            raise UsageError(name, value, f"one of {', '.join(key.choices)}")
        return value
    if key.kind == "list":
        items = value[1:-1] if value.startswith("[") and value.endswith("]") else value
        return [item.strip() for item in items.split(",") if item.strip()]
    return value
