"""What an experiment adds to the report of its sweeps beyond the comparison table: one dict, EXTRAS, keyed by the
experiment's name (conf/experiment/<name>.yaml), and NO_EXTRAS for the presets that add nothing.
tests/report/test_extras.py fails for a preset in neither, so a new experiment decides here.

A sweep's experiment is the ``experiment`` its runs recorded (an override, or the saved choice). Where no run
recorded one (runs made without a preset), or one is not named here (a plugin's preset), the extras are those
whose row key is a level of the table's rows. Either way an extra applies only where its row key is such a level:
its figures draw one line or panel per value of it. The figures and sections live in report/ beside the tables
they read (anchored_figure, anchored_targets, transfer_figure, tuning): report/ imports nothing from above it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pandas as pd

from hybrid_sysid.report.anchored_figure import ESTIMATOR, anchored_figure
from hybrid_sysid.report.anchored_targets import targets_markdown
from hybrid_sysid.report.transfer_figure import ROW, SCENARIO, transfer_figure
from hybrid_sysid.report.tuning import TUNING, tuning_figure, tuning_markdown

EXPERIMENT = "experiment"  # the config group whose choice names a sweep's experiment


@dataclass(frozen=True, eq=False)  # one per declaration: compared and hashed as itself
class Extra:
    """``row_key``: the table row level its figures draw by. ``figures``: name -> draw(table, png path).
    ``markdown``: a section in words read from the sweep directories (None: none). ``compare``: the row key its
    table's marks compare (None: the default, objective). ``paper_car``: whether the paper's figures apply beside
    its table (they are of the paper's car alone)."""

    row_key: str
    figures: dict[str, Callable[[pd.DataFrame, Path], None]] = field(default_factory=dict)
    markdown: Callable[[list[Path]], str] | None = None
    compare: str | None = None
    paper_car: bool = True


ANCHORED = Extra(
    ESTIMATOR, figures={"anchored": anchored_figure}, markdown=targets_markdown, compare=ESTIMATOR, paper_car=False
)
SCENARIOS = Extra(SCENARIO, figures={"scenarios": transfer_figure}, compare=ROW, paper_car=False)
TUNED = Extra(TUNING, figures={"tuning": tuning_figure}, markdown=tuning_markdown)

EXTRAS: dict[str, tuple[Extra, ...]] = {
    "anchored": (ANCHORED,),
    "anchored_clean": (ANCHORED,),
    "transfer": (SCENARIOS,),
    "field": (SCENARIOS,),
    "tuned": (TUNED,),
}
# the presets whose report is the comparison table and the shared figures alone
NO_EXTRAS = ("ablations", "baselines", "best", "compare", "noise_robust", "paper", "robustness")


def _unique(extras) -> tuple[Extra, ...]:
    return tuple(dict.fromkeys(extras))  # anchored and anchored_clean share one: drawn once, in the dict's order


def extras_for(df: pd.DataFrame, table: pd.DataFrame) -> tuple[Extra, ...]:
    """The extras of the experiments the runs of collect's long form recorded (EXTRAS), or by the table's row
    levels where one is unknown (see the module's docstring); only those whose row key is a level of ``table``."""
    names = set(df[EXPERIMENT].dropna().astype(str)) - {""} if EXPERIMENT in df.columns else set()
    known = names and all(n in EXTRAS or n in NO_EXTRAS for n in names)
    candidates = [e for n in EXTRAS if n in names for e in EXTRAS[n]] if known else _unique(sum(EXTRAS.values(), ()))
    levels = {str(n) for n in table.index.names}
    return _unique(e for e in candidates if e.row_key in levels)


def extras_of(table: pd.DataFrame) -> tuple[Extra, ...]:
    """A table's extras: attrs["extras"] (set by report.summary.tested_table from its runs), else those whose
    row key is a level of its rows."""
    if "extras" in table.attrs:
        return tuple(table.attrs["extras"])
    levels = {str(n) for n in table.index.names}
    return _unique(e for extras in EXTRAS.values() for e in extras if e.row_key in levels)
