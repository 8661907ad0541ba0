"""A comparison table for a terminal: the cells of summary.md (markdown.py), every one of them, in blocks at most
WIDTH characters wide, stacked. The full table's rows run to hundreds of characters and wrap into noise in a
terminal; here each block holds one parameter's noise levels (as many as fit), the row labels repeated in each."""

from __future__ import annotations

import textwrap

import pandas as pd

from hybrid_sysid.report.markdown import bound_rows, md_cell
from hybrid_sysid.report.tables import cell_columns, cell_rows, legend

WIDTH = 100  # characters: a terminal's usual width, with room to spare
GAP = "  "


class Column:
    """One column of a block: its header, one text per body row and its alignment."""

    def __init__(self, header: str, cells: list[str], left: bool = False):
        self.header, self.cells, self.left = header, cells, left
        self.width = max([len(header), *(len(line) for c in cells for line in c.split("\n"))])

    def line(self, text: str) -> str:
        return text.ljust(self.width) if self.left else text.rjust(self.width)


def _width(columns: list[Column]) -> int:
    return sum(c.width for c in columns) + len(GAP) * (len(columns) - 1)


def _labels(names: list[str], rows: list[list[str]], room: int) -> list[Column]:
    """The row labels: one column per index level, or, when those leave less than ``room`` for the cells, one
    column of "key=value, ..." wrapped to fit, a row's further lines indented."""
    columns = [Column(n, [r[i] for r in rows], left=True) for i, n in enumerate(names)]
    if _width(columns) <= WIDTH - room:
        return columns
    wrap = max(WIDTH - room, 20)
    texts = [", ".join(f"{n}={v}" for n, v in zip(names, r) if v != "") for r in rows]
    lines = [textwrap.wrap(t, wrap, subsequent_indent="  ", break_on_hyphens=False) for t in texts]
    return [Column("row", ["\n".join(line) for line in lines], left=True)]


def _block(columns: list[Column]) -> list[str]:
    lines = [GAP.join(c.line(c.header) for c in columns).rstrip(), GAP.join("-" * c.width for c in columns)]
    for i in range(len(columns[0].cells)):
        parts = [c.cells[i].split("\n") for c in columns]
        for j in range(max(len(p) for p in parts)):
            lines.append(GAP.join(c.line(p[j] if j < len(p) else "") for c, p in zip(columns, parts)).rstrip())
    return lines


def to_console(table: pd.DataFrame, compare: str | None = None, bound: pd.DataFrame | None = None) -> str:
    """The table of markdown.to_markdown (its cells, bound rows and notes, as summary.md shows them) in blocks of at
    most WIDTH characters: per parameter, its noise levels side by side as far as they fit, the counts of seeds
    and failed jobs in the last block (or one of their own); the notes wrapped to WIDTH."""
    names = [str(n) for n in table.index.names]
    rows = cell_rows(table, compare, md_cell) + bound_rows(table, bound)
    n = len(names)
    cols = cell_columns(table)
    values = [Column(f"noise {noise:g} {p} [%]", [r[n + j] for r in rows]) for j, (noise, p) in enumerate(cols)]
    counts = [Column(h, [r[n + len(cols) + i] for r in rows]) for i, h in enumerate(("seeds", "failed"))]
    room = max([_width(counts), *(c.width for c in values)]) + len(GAP)
    labels = _labels(names, [r[:n] for r in rows], room)
    blocks: list[list[Column]] = []
    for p in dict.fromkeys(p for _, p in cols):  # the parameters in table order
        block: list[Column] = []
        for column in (v for v, (_, q) in zip(values, cols) if q == p):
            if block and _width(labels + block + [column]) > WIDTH:
                blocks.append(block)
                block = []
            block.append(column)
        blocks.append(block)
    if blocks and _width(labels + blocks[-1] + counts) <= WIDTH:
        blocks[-1] = blocks[-1] + counts
    else:
        blocks.append(counts)
    text = "\n\n".join("\n".join(_block(labels + b)) for b in blocks)
    notes = ["\n".join(textwrap.wrap(note, WIDTH, break_on_hyphens=False)) for note in legend(table, compare)]
    return text + "\n" + ("\n" + "\n\n".join(notes) + "\n" if notes else "")
