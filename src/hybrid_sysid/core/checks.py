"""The one error a bad value raises, and the checks every layer shares.

``ConfigError`` carries what is wrong as data: the key (the owner's own argument name, e.g. ``kernel_size``), the
value and what is allowed. The config layer places a key under its config path (``under``: ``model.net`` +
``kernel_size``), so the owner never spells a config path and nothing parses a message. Its text is one line,
``key = value is not allowed: what is allowed`` (``key is missing: ...`` when it has none), which the
command-line entry points print as it is. It is a ValueError, so a notebook sees the usual class.
"""

from __future__ import annotations

import math
import numbers

NO_VALUE = object()  # ConfigError's value when the message shows none
DT_ALLOWED = "must be > 0 (seconds)"  # check_dt's words unless its caller has its own


class Shown(str):
    """A value given as words (``Shown("150 steps")``): a message shows it as it is, without quotes."""


def format_value(value) -> str:
    """A value as an error message shows it: as Python writes it (numpy's numbers as Python's), words as they are."""
    if isinstance(value, Shown):
        return str(value)
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return str(int(value))
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return repr(float(value))
    return repr(value)


class ConfigError(ValueError):
    """A value that is not allowed: ``key``, ``value`` (NO_VALUE: not shown) and ``allowed``; ``missing``: the key
    has no value at all."""

    def __init__(self, key: str, value=NO_VALUE, allowed: str = "", missing: bool = False):
        self.key, self.value, self.allowed, self.missing = str(key), value, str(allowed), missing
        super().__init__(self.key, value, self.allowed)

    def __str__(self) -> str:
        if self.missing:
            text = f"{self.key} is missing: {self.allowed}"
        elif self.value is NO_VALUE:
            text = f"{self.key} is not allowed: {self.allowed}"
        else:
            text = f"{self.key} = {format_value(self.value)} is not allowed: {self.allowed}"
        return " ".join(text.split())

    def with_key(self, key: str) -> "ConfigError":
        """The same error of another key (the config layer's path for an owner's argument)."""
        error = type(self)(key, self.value, self.allowed, self.missing)
        error.__cause__ = self.__cause__
        return error

    def under(self, prefix: str) -> "ConfigError":
        """The same error with its key under a config path: ``model.net`` + ``kernel_size``. A key already under
        it stays as it is."""
        if not prefix or self.key == prefix or self.key.startswith(prefix + "."):
            return self
        return self.with_key(f"{prefix}.{self.key}")


class InputError(ConfigError):
    """Input a command cannot use: a recording a user brings (data.readers), or what the estimator is given
    (inference). A ConfigError: key, value and what is allowed."""


def bad(key: str, value, allowed: str):
    """Refuse a value: the one-line error every check raises.

    Parameters
    ----------
    key : str
        The config key (or argument) named, e.g. ``data.dt``.
    value : object
        The value refused, shown as given.
    allowed : str
        What is allowed, e.g. "a float in (0, 0.036]".

    Raises
    ------
    ConfigError
        Always; its message reads ``KEY = VALUE is not allowed: ALLOWED``.
    """
    raise ConfigError(key, value, allowed)


def check_choice(key: str, value, allowed) -> None:
    """``value`` is one of ``allowed`` (a list of core.options)."""
    if value not in allowed:
        bad(key, value, f"one of {', '.join(allowed)}")


def check_number(key: str, value, low=None, high=None, *, low_open=False, high_open=False, unit: str = "") -> float:
    """A finite real number within [low, high] (an end None: unbounded; ``*_open``: excluded); returns it."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
    ok = ok and (low is None or (value > low if low_open else value >= low))
    ok = ok and (high is None or (value < high if high_open else value <= high))
    if not ok:
        bad(key, value, _range_text(low, high, low_open, high_open) + (f" ({unit})" if unit else ""))
    return float(value)


def check_positive(key: str, value, unit: str = "") -> float:
    """A finite number > 0 (a time step, a speed, a mass)."""
    return check_number(key, value, 0, low_open=True, unit=unit)


def check_dt(
    value, key: str = "dt", allowed: str = DT_ALLOWED, error: type = ConfigError, *, text=False, shown=NO_VALUE
) -> float:
    """A time step: a finite number of seconds > 0, returned as a float. Every dt the package takes is checked
    here; each entry point keeps its own words: ``key``, ``allowed``, the ``error`` class and the value ``shown``
    (the value itself by default). ``text``: anything float() reads counts (a command line's "0.002")."""
    if text:
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
    else:
        real = isinstance(value, numbers.Real) and not isinstance(value, bool)
        number = float(value) if real else math.nan
    if not (math.isfinite(number) and number > 0):
        raise error(key, value if shown is NO_VALUE else shown, allowed)
    return number


def check_int(key: str, value, low: int) -> int:
    """An integer >= low; returns it."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or int(value) != value or value < low:
        bad(key, value, f"must be an integer >= {low}")
    return int(value)


def check_pair(key: str, value) -> tuple[float, float]:
    """A (p1, p2) pair: two finite values > 0."""
    try:
        pair = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        pair = ()
    if len(pair) != 2 or not all(math.isfinite(v) and v > 0 for v in pair):
        bad(key, value, "must be two finite values > 0 (p1, p2)")
    return pair


def _range_text(low, high, low_open, high_open) -> str:
    if low is not None and high is not None:
        return f"must lie in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
    if low is not None:
        return f"must be {'>' if low_open else '>='} {low:g}"
    if high is not None:
        return f"must be {'<' if high_open else '<='} {high:g}"
    return "must be a finite number"
