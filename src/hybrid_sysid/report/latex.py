"""A comparison table as LaTeX (booktabs: needs \\usepackage{booktabs}), narrow enough for a page: the noise levels
in blocks under \\multicolumn headers, each row in two lines (the cell and its interval)."""

from __future__ import annotations

import re

import pandas as pd

from hybrid_sysid.report.tables import BEST, WORSE, as_tuple, cell_columns, cell_rows, legend, row_label, tex


def tex_cell(mean: str, std: str | None, ci: str | None, mark: str) -> tuple[str, str]:
    """A LaTeX cell in two lines: "$m \\pm s$" (bold when best, ^\\dagger when worse), and its interval "$[a, b]$"
    ("" without one)."""
    body = mean if std is None else f"{mean} \\pm {std}"
    body = f"\\mathbf{{{body}}}" if mark == BEST else body
    main = f"${body}^{{\\dagger}}$" if mark == WORSE else f"${body}$"
    return main, "" if ci is None else f"${ci}$"


TEXT_WIDTH_PT = 345.0  # LaTeX's article class at 10pt: the narrowest common text width, what to_latex fits
LATEX_SIZE = r"\footnotesize"  # the table's type; the intervals are a size smaller
LATEX_SEP_PT = 4.0  # \tabcolsep in the table (LaTeX's default: 6pt)
# widths in pt of characters in \footnotesize (Computer Modern), measured with pdflatex; others: _CHAR_PT
_CHAR_WIDTHS = {**dict.fromkeys("0123456789", 4.25), ".": 2.4, ",": 2.4, " ": 2.8, "[": 2.4, "]": 2.4, "±": 10.4}
_CHAR_WIDTHS |= {"†": 4.0, "_": 6.6, "-": 3.0, "(": 3.3, ")": 3.3, "=": 6.6}
_CHAR_PT = 4.4  # a letter, on average (upper case is wider: 6 pt)
_SCRIPT = 0.8  # \scriptsize against \footnotesize


def tex_width(tex: str) -> float:
    """An estimate of the width in pt of a table cell's LaTeX in LATEX_SIZE: a little over, not under."""
    scale = _SCRIPT if r"\scriptsize" in tex else 1.0
    scale *= 1.1 if r"\mathbf" in tex else 1.0
    text = tex.replace(r"\scriptsize", "").replace(r"\mathbf", "").replace(r"^{\dagger}", "†").replace(r"\pm", "±")
    text = text.replace(r"\_", "_").replace(r"\%", "%").replace(r"\&", "&").replace(r"\#", "#")
    text = re.sub(r"\$[^$]*\$", lambda m: m.group(0).replace(" ", ""), text)  # spacing in math: in the widths
    text = text.replace("$", "").replace("{", "").replace("}", "").replace("\\", "")
    return scale * sum(_CHAR_WIDTHS.get(c, 6.0 if c.isupper() else _CHAR_PT) for c in text)


def _levels_per_block(labels: list[list[str]], cells: list[list[str]], n_params: int, n_levels: int) -> int:
    """The most noise levels side by side (at least 1) whose estimated table width fits TEXT_WIDTH_PT: labels,
    the label and count columns (header included); cells, every cell text (both lines)."""
    fixed = sum(max(map(tex_width, col)) + 2 * LATEX_SEP_PT for col in zip(*labels))
    cell = max((tex_width(c) for row in cells for c in row), default=0.0) + 2 * LATEX_SEP_PT
    fits = int((TEXT_WIDTH_PT - fixed) // (cell * max(n_params, 1)))
    return max(1, min(fits, n_levels))


def to_latex(
    table: pd.DataFrame, compare: str | None = None, caption: str | None = None, levels_per_block: int | None = None
) -> str:
    """The same table as LaTeX (booktabs: needs \\usepackage{booktabs}), narrow enough for a page: the noise
    levels in blocks of ``levels_per_block`` (default: as many as fit TEXT_WIDTH_PT, by an estimate of the
    cells' widths), stacked, each block headed by a \\multicolumn per noise level over its parameters and a
    \\cmidrule under it; every row in two lines, "$m \\pm s$" (\\mathbf for the best row of a column,
    ^\\dagger where it is worse) and below it its interval; in LATEX_SIZE type. The rule and warnings follow as
    text.

    Parameters
    ----------
    table : pandas.DataFrame
        A comparison table (``report.tables``).
    compare : str, optional
        The swept key whose rows the marks compare (default ``objective``).
    caption : str, optional
        With it, a table float.
    levels_per_block : int, optional
        Noise levels side by side in one block.

    Returns
    -------
    str
        The LaTeX source.
    """
    cols = cell_columns(table)
    names = [tex(str(n)) for n in table.index.names]
    nl = len(names)
    levels = list(dict.fromkeys(n for n, _ in cols))
    params = list(dict.fromkeys(p for _, p in cols)) or [""]
    rows = [
        ([tex(v) for v in r[:nl]], [(main, rf"{{\scriptsize {ci}}}" if ci else "") for main, ci in r[nl:-2]])
        for r in cell_rows(table, compare, tex_cell, missing=("n/a", ""))
    ]
    per = levels_per_block or _levels_per_block(
        [names] + [labels for labels, _ in rows],
        [[t for c in cells for t in c] for _, cells in rows] + [[tex(str(p)) for p in params]],
        len(params),
        len(levels),
    )
    blocks = [levels[i : i + per] for i in range(0, len(levels), per)] or [[]]
    per = max(len(b) for b in blocks)
    index = {c: j for j, c in enumerate(cols)}

    def line(cells: list[str]) -> str:
        return " & ".join(cells) + r" \\"

    out = [
        "{" + LATEX_SIZE + rf"\setlength{{\tabcolsep}}{{{LATEX_SEP_PT:g}pt}}%",
        rf"\begin{{tabular}}{{{'l' * nl}{'r' * (per * len(params))}}}",
        r"\toprule",
    ]
    for b, block in enumerate(blocks):
        if b:
            out.append(r"\midrule")
        pad = per - len(block)
        group = rf"\multicolumn{{{len(params)}}}{{c}}"
        out.append(line([""] * nl + [f"{group}{{noise {n:g}}}" for n in block] + [group + "{}"] * pad))
        if block:
            out.append(
                "".join(
                    rf"\cmidrule(lr){{{nl + 1 + i * len(params)}-{nl + (i + 1) * len(params)}}}"
                    for i in range(len(block))
                )
            )
        out.append(line(names + [tex(str(p)) for p in params] * len(block) + [""] * (pad * len(params))))
        out.append(r"\midrule")
        for labels, cells in rows:
            found = [cells[index[(n, p)]] if (n, p) in index else ("", "") for n in block for p in params]
            found += [("", "")] * (pad * len(params))
            out.append(line(labels + [main for main, _ in found]))
            if any(ci for _, ci in found):
                out.append(line([""] * nl + [ci for _, ci in found]))
    out += [r"\bottomrule", r"\end{tabular}}"]
    body = "\n".join(out) + "\n"
    if caption:
        body = "\n".join([r"\begin{table}", r"\centering", rf"\caption{{{tex(caption)}}}", body + r"\end{table}"])
        body += "\n"
    notes = [_counts_note(table), *legend(table, compare, latex=True)]
    return body + "\n" + "\n\n".join(notes) + "\n"


def _counts_note(table: pd.DataFrame) -> str:
    """The LaTeX table's seeds and failed jobs per row, as a sentence (one figure each when every row has the
    same), so that the table's columns are all cells."""
    seeds, failed = table[("n_seeds", "", "")].astype(int), table[("n_failed", "", "")].astype(int)
    if len(table) == 0:
        return "No rows."
    if seeds.nunique() == 1 and failed.nunique() == 1:
        return f"Completed seeds per row: {seeds.iloc[0]}; failed or unreadable jobs per row: {failed.iloc[0]}."
    per_row = "; ".join(
        f"{tex(row_label(table.index.names, as_tuple(label)))}: {s} ({f})"
        for label, s, f in zip(table.index, seeds, failed)
    )
    return f"Completed seeds (failed or unreadable jobs) per row: {per_row}."
