"""Comparison tables for a paper: mean ± seed spread per cell, the best row marked, and whether each other
row's gap to it exceeds the seed spread. GitHub markdown and LaTeX (booktabs).

The rule (one line, printed under every table): in each column, among rows that differ only in the compared key
(``objective`` when it is swept), the lowest mean is **bold**; a row is marked † when its gap to the bold row is
larger than the combined seed spread, |m_a - m_b| > s_a + s_b (s: sample standard deviations over seeds,
ddof=1). A row with fewer than two seeds has no spread and is never marked †. Lower is better: both metrics are
errors.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

BEST, WORSE, WITHIN, UNKNOWN = "best", "worse", "within", "unknown"
DAGGER = "†"
MIN_SEEDS = 3  # rows with fewer completed seeds get a warning under the table
K_LEVEL = "K"  # the row level of test-time windows per recording, when several are present


def cell_columns(table: pd.DataFrame) -> list[tuple]:
    """The (noise_std, parameter) pairs that have a "mean" column, in table order."""
    return [c[:2] for c in table.columns if c[2] == "mean"]


def compared_level(table: pd.DataFrame, compare: str | None = None) -> str | None:
    """The index level whose values are compared: ``compare`` if given, else ``objective`` when it is a level,
    else the first level that is not K. None for the single "all" row."""
    names = [str(n) for n in table.index.names]
    if compare is not None:
        if compare not in names:
            raise ValueError(f"compare={compare!r} is not a row key of the table; row keys: {names}")
        return compare
    if "objective" in names:
        return "objective"
    candidates = [n for n in names if n not in (K_LEVEL, "all")]
    return candidates[0] if candidates else None


def compare_marks(table: pd.DataFrame, compare: str | None = None) -> pd.DataFrame:
    """One mark per row and (noise_std, parameter) column: "best" (lowest mean of its group), "worse" (gap to the
    best > s_best + s_row), "within" (gap <= that), "unknown" (a spread is missing: fewer than 2 seeds), or ""
    (no mean, or no other row to compare with). A group is the rows sharing every index level but the
    compared one."""
    cols = cell_columns(table)
    marks = pd.DataFrame("", index=table.index, columns=pd.MultiIndex.from_tuples(cols) if cols else None)
    level = compared_level(table, compare)
    if level is None or not cols:
        return marks
    others = [n for n in table.index.names if n != level]
    positions = np.arange(len(table))
    if others:
        frame = table.index.to_frame(index=False)
        groups = [g.index.to_numpy() for _, g in frame.groupby(others, sort=False, dropna=False)]
    else:
        groups = [positions]
    for col in cols:
        mean = table[(*col, "mean")].astype(float).to_numpy()
        std = table[(*col, "std")].astype(float).to_numpy()
        for rows in groups:
            rows = [r for r in rows if not math.isnan(mean[r])]
            if len(rows) < 2:
                continue
            best = min(rows, key=lambda r: mean[r])  # first of equal means
            marks.iloc[best, cols.index(col)] = BEST
            for r in rows:
                if r == best:
                    continue
                if math.isnan(std[r]) or math.isnan(std[best]):
                    mark = UNKNOWN
                else:
                    mark = WORSE if abs(mean[r] - mean[best]) > std[r] + std[best] else WITHIN
                marks.iloc[r, cols.index(col)] = mark
    return marks


def _number(v: float, as_percent: bool) -> str:
    return f"{100 * v:.2f}" if as_percent else f"{v:.4f}"


def _labels(table: pd.DataFrame, label) -> list[str]:
    return [str(v) if v != "" else "(default)" for v in (label if isinstance(label, tuple) else (label,))]


def _row_name(table: pd.DataFrame, label) -> str:
    if list(table.index.names) == ["all"]:
        return "all"
    return ", ".join(f"{n}={v}" for n, v in zip(table.index.names, _labels(table, label)))


def legend(table: pd.DataFrame, compare: str | None = None, marked: bool = True) -> list[str]:
    """The lines under a table: the marking rule (one line) and a warning for rows with fewer than 3 seeds."""
    lines = []
    level = compared_level(table, compare)
    if marked and level is not None and cell_columns(table):
        lines.append(f"**Bold**: lowest mean in its column among rows that differ only in `{level}`; "
                     f"{DAGGER}: its gap to the bold cell exceeds the combined seed spread, "
                     f"`|m_a - m_b| > s_a + s_b` (s: std over seeds, ddof=1); unmarked: within that spread, "
                     f"or fewer than 2 seeds.")
    few = [(label, int(row[("n_seeds", "", "")])) for label, row in table.iterrows()
           if int(row[("n_seeds", "", "")]) < MIN_SEEDS]
    if few:
        lines.append(f"Warning: fewer than {MIN_SEEDS} seeds in "
                     + "; ".join(f"{_row_name(table, label)} ({n})" for label, n in few)
                     + ": the spread over seeds is unreliable there.")
    return lines


def to_markdown(table: pd.DataFrame, as_percent: bool = True, compare: str | None = None,
                marked: bool = True, notes: bool = True) -> str:
    """A GitHub markdown table: one column per (noise, parameter) with "mean ± std" over seeds (std, ddof=1,
    omitted for a single seed), then the counts of completed seeds and failed jobs; with ``marked``, the best
    row of each column in bold and † where the gap to it exceeds the seed spread; with ``notes``, the rule and
    the few-seeds warning under the table."""
    cells = cell_columns(table)
    marks = compare_marks(table, compare) if marked else None
    unit = " [%]" if as_percent else ""
    header = [str(n) for n in table.index.names] + [f"noise {n:g} {p}{unit}" for n, p in cells] + ["seeds", "failed"]
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join([" --- "] * table.index.nlevels + [" ---: "] * (len(header) - table.index.nlevels)) + "|"]
    for i, (label, row) in enumerate(table.iterrows()):
        out = _labels(table, label)
        for j, (n, p) in enumerate(cells):
            mean, std = row[(n, p, "mean")], row[(n, p, "std")]
            text = "n/a" if pd.isna(mean) else _number(mean, as_percent)
            text = text if pd.isna(std) or pd.isna(mean) else f"{text} ± {_number(std, as_percent)}"
            mark = marks.iloc[i, j] if marks is not None else ""
            out.append(f"**{text}**" if mark == BEST else f"{text} {DAGGER}" if mark == WORSE else text)
        out += [str(int(row[("n_seeds", "", "")])), str(int(row[("n_failed", "", "")]))]
        lines.append("| " + " | ".join(v.replace("|", "\\|") for v in out) + " |")
    text = "\n".join(lines) + "\n"
    extra = legend(table, compare, marked) if notes else []
    return text + ("\n" + "\n\n".join(extra) + "\n" if extra else "")


def _tex(s: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    out = s.replace("\\", "\0")
    for a in "_%&#${}":
        out = out.replace(a, "\\" + a)
    return out.replace("\0", r"\textbackslash{}").replace("±", r"$\pm$")


def to_latex(table: pd.DataFrame, as_percent: bool = True, compare: str | None = None,
             caption: str | None = None) -> str:
    """The same table as LaTeX (needs \\usepackage{booktabs}): $m \\pm s$ cells, \\mathbf for the best row of a
    column, ^\\dagger where the gap to it exceeds the seed spread; the rule and warnings follow as text."""
    cells = cell_columns(table)
    marks = compare_marks(table, compare)
    nl = table.index.nlevels
    unit = r" [\%]" if as_percent else ""
    header = [_tex(str(n)) for n in table.index.names] + [f"{n:g} {_tex(str(p))}" for n, p in cells] \
        + ["seeds", "failed"]
    lines = [r"\begin{tabular}{" + "l" * nl + "r" * (len(header) - nl) + "}", r"\toprule"]
    if cells:
        lines.append(" & ".join([""] * nl) + f" & \\multicolumn{{{len(cells)}}}{{c}}{{noise std [m/s$^2$], "
                     f"parameter{unit}}} & & \\\\")
        lines.append(f"\\cmidrule(lr){{{nl + 1}-{nl + len(cells)}}}")
    lines += [" & ".join(header) + r" \\", r"\midrule"]
    for i, (label, row) in enumerate(table.iterrows()):
        out = [_tex(v) for v in _labels(table, label)]
        for j, (n, p) in enumerate(cells):
            mean, std = row[(n, p, "mean")], row[(n, p, "std")]
            if pd.isna(mean):
                out.append("n/a")
                continue
            body = _number(mean, as_percent) + ("" if pd.isna(std) else f" \\pm {_number(std, as_percent)}")
            mark = marks.iloc[i, j]
            out.append(f"$\\mathbf{{{body}}}$" if mark == BEST else
                       f"${body}^{{\\dagger}}$" if mark == WORSE else f"${body}$")
        out += [str(int(row[("n_seeds", "", "")])), str(int(row[("n_failed", "", "")]))]
        lines.append(" & ".join(out) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    notes = [ln.replace("**Bold**", "Bold").replace("`", "").replace(DAGGER, "$^\\dagger$")
             for ln in legend(table, compare)]
    notes = [_tex_text(ln) for ln in notes]
    body = "\n".join(lines)
    if caption:
        body = "\\begin{table}\n\\centering\n" + body + f"\n\\caption{{{_tex(caption)}}}\n\\end{{table}}"
    return body + "\n" + ("\n" + "\n\n".join(notes) + "\n" if notes else "")


def _tex_text(line: str) -> str:
    """Legend prose in LaTeX: escape specials but keep the $^\\dagger$ produced above, write |x| as math."""
    keep = "$^\\dagger$"
    parts = line.split(keep)
    parts = [_tex(p).replace("|m\\_a - m\\_b| > s\\_a + s\\_b", "$|m_a - m_b| > s_a + s_b$") for p in parts]
    return keep.join(parts)
