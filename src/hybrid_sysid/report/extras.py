"""What an experiment adds to the report of its sweeps beyond the comparison table, declared by the experiment.

An experiment whose table rows carry a key of its own (experiment=transfer's ``scenario``, experiment=tuned's
``tuning``) registers an ``Extra`` for that key in its own module (hybrid_sysid.experiments). The report calls
every extra whose key is among a table's rows, in a sweep's summary and on a results page alike, so a new
experiment adds code to experiments/ and conf/, not here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pandas as pd


@dataclass(frozen=True)
class Extra:
    """``row_key``: the table row level that marks the experiment's tables. ``figures``: name -> draw(table, png
    path). ``markdown``: a section in words read from the sweep directories (None: none). ``compare``: the row
    key its table's marks compare (None: the default, objective). ``paper_car``: whether the paper's figures
    apply beside its table (they are of the paper's car alone)."""

    row_key: str
    figures: dict[str, Callable[[pd.DataFrame, Path], None]] = field(default_factory=dict)
    markdown: Callable[[list[Path]], str] | None = None
    compare: str | None = None
    paper_car: bool = True


_REGISTERED: dict[str, Extra] = {}


def register(extra: Extra) -> None:
    """Declare an experiment's additions (once per row key: a second registration replaces the first)."""
    _REGISTERED[extra.row_key] = extra


def extras_of(table: pd.DataFrame) -> list[Extra]:
    """The extras whose row key is a level of the table's rows."""
    names = {str(n) for n in table.index.names}
    return [e for key, e in _REGISTERED.items() if key in names]
