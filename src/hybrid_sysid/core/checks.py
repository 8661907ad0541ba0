"""The one-line value checks every layer shares: an error names the key, the value and what is allowed.

``ConfigError`` is a ValueError, so code that builds an object outside a config (a notebook, a test) sees the
usual exception class, and the command-line entry points print its message on one line.
"""

from __future__ import annotations

import math
import numbers


class ConfigError(ValueError):
    """A value outside what is allowed; the message names the key, the value and the allowed range."""


def format_value(value) -> str:
    """A value as an error message shows it: numbers in %g, anything else by repr."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return f"{value:g}"
    return repr(value)


def bad(key: str, value, allowed: str):
    """Raise ConfigError: ``key = value is not allowed: allowed``."""
    raise ConfigError(f"{key} = {value!r} is not allowed: {allowed}")


def check_choice(key: str, value, allowed) -> None:
    """``value`` is one of ``allowed`` (an options.py list)."""
    if value not in allowed:
        raise ConfigError(f"{key} = {format_value(value)} is not allowed: one of {', '.join(allowed)}")


def check_pair(name: str, value) -> tuple[float, float]:
    """A (p1, p2) pair: two finite values > 0."""
    pair = tuple(float(v) for v in value)
    if len(pair) != 2 or not all(math.isfinite(v) and v > 0 for v in pair):
        raise ValueError(f"{name} = {value} is invalid; it must be two finite values > 0 (p1, p2)")
    return pair


def check_int(name: str, value, low: int) -> int:
    if isinstance(value, bool) or int(value) != value or value < low:
        raise ValueError(f"{name} = {value} is invalid; it must be an integer >= {low}")
    return int(value)
