"""A comparison table as GitHub markdown (pandas' to_markdown, through tabulate): "mean ± std" over seeds in
percent, the best row of each column in bold, † where a row is worse, the rule and warnings under it."""

from __future__ import annotations

import pandas as pd

from hybrid_sysid.report.tables import BEST, DAGGER, WORSE, cell_columns, cell_rows, legend


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


def to_markdown(table: pd.DataFrame, compare: str | None = None) -> str:
    """A GitHub markdown table: one column per (noise, parameter) with "mean ± std" over seeds in percent, then
    the counts of completed seeds and failed jobs; the best row of each column in bold and † where the gap to it
    exceeds the seed spread; the rule and the few-seeds warning under the table."""
    header = (
        [str(n) for n in table.index.names]
        + [f"noise {n:g} {p} [%]" for n, p in cell_columns(table)]
        + ["seeds", "failed"]
    )
    notes = legend(table, compare)
    return markdown_table(header, cell_rows(table, compare, md_cell), table.index.nlevels) + (
        "\n" + "\n\n".join(notes) + "\n" if notes else ""
    )
