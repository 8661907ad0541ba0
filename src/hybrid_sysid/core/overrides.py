"""One reading of Hydra's override strings, for every module that asks which key an override sets and to what:
``key=value``, ``+key=value`` (add), ``++key=value`` (add or change), ``~key`` and ``~key=value`` (delete), and a
group with a package, ``group@package=value``.

Plain text, not Hydra's grammar: what a run's record holds was Hydra's to accept, and reading it must not fail
on a value Hydra's parser would refuse in isolation. tests/core/test_overrides.py holds it against Hydra's own
parser (hydra.core.override_parser.overrides_parser.OverridesParser) over the forms the package meets.
"""

from __future__ import annotations

from typing import Iterable, NamedTuple

PREFIXES = ("++", "+", "~")  # longest first: "++" is not "+" then "+key"


class Override(NamedTuple):
    """An override string, parsed: ``prefix`` ("", "+", "++" or "~"), ``key`` (the dotted key or config group,
    with its "@package" when given) and ``value`` (the text after the first "=", as given; None without one)."""

    prefix: str
    key: str
    value: str | None

    @property
    def deletes(self) -> bool:
        return self.prefix == "~"

    @property
    def group(self) -> str:
        """The config group or key without its package: ``model@extra`` -> ``model``."""
        return self.key.split("@")[0]

    @property
    def unprefixed(self) -> str:
        """The override without its prefix: ``+logger=mlflow`` -> ``logger=mlflow``, ``~objective`` -> ``objective``."""
        return self.key if self.value is None else f"{self.key}={self.value}"

    @property
    def written_key(self) -> str:
        """The key as written, with its prefix (Hydra's ``Override.get_key_element``)."""
        return self.prefix + self.key


def parse_override(text) -> Override:
    """``"+model.optim.lr=0.1"`` -> ``Override("+", "model.optim.lr", "0.1")``; ``"~objective"`` ->
    ``Override("~", "objective", None)``."""
    head, sep, value = str(text).partition("=")
    prefix = next((p for p in PREFIXES if head.startswith(p)), "")
    return Override(prefix, head[len(prefix) :], value if sep else None)


def parse_overrides(texts: Iterable) -> list[Override]:
    """Each of ``texts`` parsed; [] for anything but a list or tuple (a record's field edited to text, say)."""
    return [parse_override(t) for t in texts] if isinstance(texts, (list, tuple)) else []
