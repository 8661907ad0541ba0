"""A comparison table as GitHub markdown (pandas' to_markdown, through tabulate): "mean ± std" over seeds in
percent, the best row of each column in bold, † where a row is worse, the rule and warnings under it."""

from __future__ import annotations

import pandas as pd

from hybrid_sysid.report.stats import K_LEVEL
from hybrid_sysid.report.tables import BEST, BOUND_LABEL, DAGGER, WORSE, cell_columns, cell_rows, legend


def md_cell(mean: str, std: str | None, ci: str | None, mark: str) -> str:
    text = mean if std is None else f"{mean} ± {std}"
    text = f"**{text}**" if mark == BEST else text
    text = text if ci is None else f"{text} {ci}"
    return f"{text} {DAGGER}" if mark == WORSE else text


def markdown_table(header: list[str], rows: list[list[str]], n_left: int) -> str:
    """A GitHub markdown table (pandas' to_markdown, through tabulate), its first n_left columns left-aligned
    and the others right-aligned; cells are shown as given (no number parsing)."""
    frame = pd.DataFrame(
        [[str(c).replace("|", "\\|") for c in r] for r in rows], columns=[str(h).replace("|", "\\|") for h in header]
    )
    align = ["left"] * n_left + ["right"] * (len(header) - n_left)
    return frame.to_markdown(index=False, colalign=align, disable_numparse=True) + "\n"


def bound_rows(table: pd.DataFrame, bound: pd.DataFrame | None) -> list[list[str]]:
    """The table's Cramér-Rao bound rows (report.tables.bound_table), one per K, in its columns: the label in the
    first level, K in its level, the bound in percent under each (noise, parameter), the counts left empty."""
    if bound is None or bound.empty:
        return []
    names = [str(n) for n in table.index.names]
    rows = []
    for k, values in bound.iterrows():
        if K_LEVEL not in names and len(bound) > 1 and k != bound.index.min():
            continue  # a table without a K level shows K = 1's bound, as its cells are K = 1's
        label = [BOUND_LABEL] + [str(k) if n == K_LEVEL else "" for n in names[1:]]
        cells = [f"{100 * values[c]:.2f}" if c in values.index else "" for c in cell_columns(table)]
        rows.append(label + cells + ["", ""])
    return rows


def to_markdown(table: pd.DataFrame, compare: str | None = None, bound: pd.DataFrame | None = None) -> str:
    """A GitHub markdown table: one column per (noise, parameter) with "mean ± std" over seeds in percent, then
    the counts of completed seeds and failed jobs; the best row of each column in bold and † where the gap to it
    exceeds the seed spread; with ``bound`` (report.tables.bound_table) a last row per K, the Cramér-Rao bound; the
    rule and the few-seeds warning under the table."""
    header = (
        [str(n) for n in table.index.names]
        + [f"noise {n:g} {p} [%]" for n, p in cell_columns(table)]
        + ["seeds", "failed"]
    )
    notes = legend(table, compare)
    rows = cell_rows(table, compare, md_cell) + bound_rows(table, bound)
    return markdown_table(header, rows, table.index.nlevels) + ("\n" + "\n\n".join(notes) + "\n" if notes else "")
