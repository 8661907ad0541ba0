"""Command-line overrides as Hydra's grammar reads them, whatever the characters of a path.

Hydra's override grammar allows only ASCII letters, digits and a few signs in an unquoted value, so
``hydra.run.dir=lauf_ü`` or ``init_from=läufe/run`` is a lexer error in any locale. Under an ASCII locale
(``LC_ALL=C`` without UTF-8 mode) Python hands such an argument over with lone surrogates, which the grammar
refuses too. A quoted value may hold any character (Hydra's documented override grammar), so a plain value
holding characters outside ASCII is quoted before Hydra reads it. Its string is the one the shell gave: the
surrogates of an ASCII locale stay, so the path's bytes reach the file system as they were.
"""

from __future__ import annotations

# a value with any of these is Hydra syntax (quotes, escapes, lists, dicts, sweeps' functions, interpolations):
# left to Hydra as written
SYNTAX = set("'\"\\()[]{}$=")
# Hydra's options that take the next argument as their value (a path may hold "=")
TAKES_VALUE = {"--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd", "--cfg", "-c", "--package", "-p"}
TAKES_VALUE |= {"--experimental-rerun"}


def quoted_value(value: str) -> str:
    """``value`` with each comma-separated item holding characters outside ASCII in single quotes (a sweep's
    items stay items); any other value as it is. A digit outside ASCII is left to Hydra's refusal: quoted, a
    number field would read the Arabic-Indic ``٣`` as 3."""
    if value.isascii() or SYNTAX & set(value) or any(c.isdigit() and not c.isascii() for c in value):
        return value
    return ",".join(item if item.isascii() else f"'{item}'" for item in value.split(","))


def quoted_overrides(args: list[str]) -> list[str]:
    """The command line with the values of key=value overrides quoted where Hydra's grammar needs it; options
    (``-m``, ``--config-dir DIR``) and their arguments as they are."""
    out, after_option = [], False
    for arg in args:
        key, sep, value = arg.partition("=")
        plain = sep and not arg.startswith("-") and not after_option
        out.append(f"{key}={quoted_value(value)}" if plain else arg)
        after_option = arg in TAKES_VALUE  # its argument (--config-dir DIR) is no override
    return out
