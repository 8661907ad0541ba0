"""The comparison table of a sweep: mean ± seed spread and a confidence interval per cell, the best row marked,
and whether each other row is worse than it; as GitHub markdown (pandas + tabulate) and LaTeX (booktabs, the
noise levels in blocks under \\multicolumn headers, narrow enough for a page).

The spread over seeds is the sample standard deviation (ddof=1); the interval is the 95% Student t interval of
the mean over seeds (scipy.stats.t; seeds are the independent repetitions, and with 3 of them it is wide). With a
single seed neither is shown. The marks (the rule is printed under every table): in each column, among rows
that differ only in the compared key (``objective`` when it is swept, ``row`` in experiment=transfer's
table), the lowest mean is **bold**. Where a row
and the bold row share their test recordings and the per-recording predictions are at hand (``paired``), a row is
marked † when a two-sided Wilcoxon signed-rank test (scipy.stats.wilcoxon) on the per-recording relative
deviations, averaged over seeds, finds a difference at p < 0.05; otherwise when its gap to the bold row is larger
than the combined seed spread, |m_a - m_b| > s_a + s_b (rows with fewer than two seeds are then never marked).
Lower is better: both metrics are errors.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
from scipy import stats

from hybrid_sysid.report.collect import natural_key, row_keys

METRICS = {"mean_rel_dev": "mean relative deviation", "std_rel_dev": "std of relative deviation"}
BEST, WORSE, WITHIN, UNKNOWN = "best", "worse", "within", "unknown"
DAGGER = "†"
MIN_SEEDS = 3  # rows with fewer completed seeds get a warning under the table
K_LEVEL = "K"  # the row level of test-time windows per recording, when several are present
NO_KEYS = "all"  # the single row label when no override varies across runs
CONFIDENCE = 0.95  # of the interval over seeds
ALPHA = 0.05  # the paired test's level for †


def summary_table(df: pd.DataFrame, split: str = "test", metric: str = "mean_rel_dev") -> pd.DataFrame:
    """From collect's long form. Rows: the swept values other than seed ("all" if none vary), plus a level "K"
    when rows sharing those values hold more than one windows value. Columns (noise_std, parameter, stat): stat
    "mean", "std" (ddof=1), "ci_low" and "ci_high" (t_interval) of the metric over the completed seeds; then
    ("n_seeds", "", "") counting completed
    runs (with a K level: completed runs with results at that K) and ("n_failed", "", "") counting the others."""
    if metric not in METRICS:
        raise ValueError(f"metric={metric!r} is not one of {list(METRICS)}")
    keys = row_keys(df)
    if not keys:
        df, keys = df.assign(**{NO_KEYS: NO_KEYS}), [NO_KEYS]
    runs = df.drop_duplicates("run")
    done = runs.status == "completed"
    counts = pd.DataFrame({"n_seeds": done, "n_failed": ~done}).groupby([runs[k] for k in keys]).sum().astype(int)

    sub = df[(df.status == "completed") & (df.split == split)]
    rows = keys
    if len(sub) and sub.groupby(keys).windows.nunique().max() > 1:  # several K under one row: K is a level
        sub, rows = sub.assign(**{K_LEVEL: sub.windows}), keys + [K_LEVEL]
        ks = sorted(sub[K_LEVEL].dropna().unique())
        index = pd.MultiIndex.from_tuples([(*_as_tuple(c), k) for c in counts.index for k in ks], names=rows)
        seeds = sub.groupby(rows).run.nunique().reindex(index).fillna(0).astype(int)
        counts = pd.DataFrame(
            {"n_seeds": seeds.to_numpy(), "n_failed": np.repeat(counts.n_failed.to_numpy(), len(ks))}, index=index
        )
    counts.columns = pd.MultiIndex.from_tuples([(c, "", "") for c in counts.columns])

    names = ["noise_std", "parameter", "stat"]
    if len(sub):
        stat = sub.groupby(rows + names[:2])[metric].agg(
            mean="mean",
            std=lambda s: s.std(ddof=1),
            ci_low=lambda s: t_interval(s)[0],
            ci_high=lambda s: t_interval(s)[1],
        )
        cells = stat.stack().unstack(names[:2] + [-1]).sort_index(axis=1)  # noise, parameter, mean|std
    else:
        cells = pd.DataFrame(index=counts.index, columns=pd.MultiIndex.from_tuples([], names=names))
    table = pd.concat([cells.reindex(counts.index), counts], axis=1)
    table.columns = table.columns.set_names(names)
    return table.iloc[sorted(range(len(table)), key=lambda i: natural_key(table.index[i]))]


def t_interval(values) -> tuple[float, float]:
    """The CONFIDENCE Student t interval of the mean of values (NaN, NaN with fewer than two)."""
    v = np.asarray(values, dtype=float)
    if len(v) < 2:
        return math.nan, math.nan
    if np.ptp(v) == 0:  # seeds that agree (a baseline without randomness): the interval is the value itself
        return float(v[0]), float(v[0])
    low, high = stats.t.interval(CONFIDENCE, len(v) - 1, loc=v.mean(), scale=stats.sem(v))
    return float(low), float(high)


def paired_deviations(preds: pd.DataFrame, df: pd.DataFrame, table: pd.DataFrame) -> dict:
    """For the paired test: table row label -> DataFrame (index recording, columns (noise_std, parameter)) of
    the per-recording relative deviations averaged over the row's seeds. ``preds``: collect.load_predictions;
    ``df``: collect's long form, which gives each run its row."""
    if preds.empty:
        return {}
    names = [str(n) for n in table.index.names]
    keys = [n for n in names if n not in (K_LEVEL, NO_KEYS)]
    runs = df.drop_duplicates("run").set_index("run")[keys] if keys else None
    p = preds.join(runs, on="run") if keys else preds.assign(**{NO_KEYS: NO_KEYS})
    if K_LEVEL in names:
        p = p.assign(**{K_LEVEL: p.windows})
    rows = [n for n in names]
    mean = p.groupby(rows + ["recording", "noise_std", "parameter"]).rel_dev.mean().unstack(["noise_std", "parameter"])
    out = {}
    for label, frame in mean.groupby(level=rows if len(rows) > 1 else rows[0]):
        out[label] = frame.droplevel(rows)
    return out


def wilcoxon_p(a, b) -> float:
    """Two-sided p-value of the Wilcoxon signed-rank test of paired samples; 1 when they are equal."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if not np.any(d):
        return 1.0
    return float(stats.wilcoxon(a, b).pvalue)


def _paired_p(paired: dict | None, label_a, label_b, col) -> float | None:
    """The paired test's p-value between two rows in a column, None when either lacks per-recording data or
    they do not share their recordings."""
    if not paired or label_a not in paired or label_b not in paired:
        return None
    a, b = paired[label_a], paired[label_b]
    if col not in a.columns or col not in b.columns:
        return None
    a, b = a[col].dropna(), b[col].dropna()
    if len(a) < 2 or not a.index.sort_values().equals(b.index.sort_values()):
        return None
    return wilcoxon_p(a.sort_index().to_numpy(), b.sort_index().to_numpy())


def _as_tuple(label) -> tuple:
    return label if isinstance(label, tuple) else (label,)


def cell_columns(table: pd.DataFrame) -> list[tuple]:
    """The (noise_std, parameter) pairs that have a "mean" column, in table order."""
    return [c[:2] for c in table.columns if c[2] == "mean"]


def compared_level(table: pd.DataFrame, compare: str | None = None) -> str | None:
    """The index level whose values are compared: ``compare`` if given, else ``objective`` when it is a level,
    else ``row`` (experiment=transfer's table) when it is one, else the first level that is not K. None for the
    single "all" row."""
    names = [str(n) for n in table.index.names]
    if compare is not None:
        if compare not in names:
            raise ValueError(f"compare={compare!r} is not a row key of the table; row keys: {names}")
        return compare
    for preferred in ("objective", "row"):  # "row": experiment=transfer's rows within a scenario
        if preferred in names:
            return preferred
    candidates = [n for n in names if n not in (K_LEVEL, NO_KEYS)]
    return candidates[0] if candidates else None


def compare_marks(table: pd.DataFrame, compare: str | None = None, paired: dict | None = None) -> pd.DataFrame:
    """One mark per row and (noise_std, parameter) column: "best" (lowest mean of its group, the first of equal
    means), "worse" / "within" (by the paired test, p < ALPHA or not, where both rows have per-recording
    deviations in ``paired`` (paired_deviations; default: table.attrs["paired"]) on the same recordings; else
    by the spread rule: gap to the best > s_best + s_row or not), "unknown" (no paired data and a spread is
    missing: fewer than 2 seeds), or "" (no mean, or no other row to compare with). A group is the rows sharing
    every index level but the compared one."""
    paired = table.attrs.get("paired") if paired is None else paired
    cols = cell_columns(table)
    # no completed cell (every job failed): an empty frame of the right index, not a constructor error
    marks = (
        pd.DataFrame("", index=table.index, columns=pd.MultiIndex.from_tuples(cols))
        if cols
        else pd.DataFrame(index=table.index)
    )
    level = compared_level(table, compare)
    if level is None or not cols:
        return marks
    others = [n for n in table.index.names if n != level]
    frame = table.index.to_frame(index=False)
    groups = (
        [g.index.to_numpy() for _, g in frame.groupby(others, sort=False, dropna=False)]
        if others
        else [np.arange(len(table))]
    )
    for j, col in enumerate(cols):
        mean = table[(*col, "mean")].astype(float).to_numpy()
        std = table[(*col, "std")].astype(float).to_numpy()
        for rows in groups:
            rows = [r for r in rows if not math.isnan(mean[r])]
            if len(rows) < 2:
                continue
            best = min(rows, key=lambda r: mean[r])
            for r in rows:
                p = None if r == best else _paired_p(paired, table.index[r], table.index[best], col)
                if r == best:
                    mark = BEST
                elif p is not None:
                    mark = WORSE if p < ALPHA else WITHIN
                elif math.isnan(std[r]) or math.isnan(std[best]):
                    mark = UNKNOWN
                else:
                    mark = WORSE if abs(mean[r] - mean[best]) > std[r] + std[best] else WITHIN
                marks.iloc[r, j] = mark
    return marks


def row_label(names, values) -> str:
    """'objective=hybrid, road=(default)'; 'all' for the single row of a sweep where only the seed varies."""
    names, values = list(names), list(values)
    if names == [NO_KEYS]:
        return NO_KEYS
    return ", ".join(f"{n}={v}" for n, v in zip(names, _shown(values))) or NO_KEYS


def _shown(values) -> list[str]:
    return [str(v) if v != "" else "(default)" for v in values]


def _tex(s: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    out = s.replace("\\", "\0")
    for a in "_%&#${}":
        out = out.replace(a, "\\" + a)
    return out.replace("\0", r"\textbackslash{}").replace("±", r"$\pm$")


def legend(table: pd.DataFrame, compare: str | None = None, latex: bool = False) -> list[str]:
    """The lines under a table: the interval, the marking rule (and which test made the marks), and a warning
    for rows with fewer than MIN_SEEDS seeds."""
    esc = _tex if latex else str
    bold, dagger, rule = (
        (r"\textbf{Bold}", r"$^\dagger$", r"$|m_a - m_b| > s_a + s_b$")
        if latex
        else ("**Bold**", DAGGER, "`|m_a - m_b| > s_a + s_b`")
    )
    lines = []
    level = compared_level(table, compare)
    if level is not None and cell_columns(table):
        spread = f"its gap to the bold cell exceeds the combined seed spread, {rule} (s: std over seeds, ddof=1)"
        if table.attrs.get("paired"):
            test = (
                f"a two-sided Wilcoxon signed-rank test (scipy.stats.wilcoxon) on the per-recording relative "
                f"deviations, averaged over seeds, finds it worse than the bold cell at p < {ALPHA:g} (the rows "
                f"share their test recordings; the test takes recordings, not seeds, as the sample); where "
                f"rows do not share them, {spread}"
            )
        else:
            test = spread
        lines.append(
            f"{bold}: lowest mean in its column among rows that differ only in "
            f"{esc(level) if latex else f'`{level}`'}; {dagger}: {test}; unmarked: not worse by that "
            "rule, or fewer than 2 seeds without a paired test. "
            f"[a, b]: {CONFIDENCE:.0%} Student t interval of the mean over seeds.".replace("%", r"\%" if latex else "%")
        )
    few = [(label, int(n)) for label, n in table[("n_seeds", "", "")].items() if n < MIN_SEEDS]
    if few:
        lines.append(
            f"Warning: fewer than {MIN_SEEDS} seeds in "
            + "; ".join(f"{esc(row_label(table.index.names, _as_tuple(label)))} ({n})" for label, n in few)
            + ": the spread over seeds is unreliable there."
        )
    return lines


def _md_cell(mean: str, std: str | None, ci: str | None, mark: str) -> str:
    text = mean if std is None else f"{mean} ± {std}"
    text = f"**{text}**" if mark == BEST else text
    text = text if ci is None else f"{text} {ci}"
    return f"{text} {DAGGER}" if mark == WORSE else text


def _tex_cell(mean: str, std: str | None, ci: str | None, mark: str) -> tuple[str, str]:
    """A LaTeX cell in two lines: "$m \\pm s$" (bold when best, ^\\dagger when worse), and its interval "$[a, b]$"
    ("" without one)."""
    body = mean if std is None else f"{mean} \\pm {std}"
    body = f"\\mathbf{{{body}}}" if mark == BEST else body
    main = f"${body}^{{\\dagger}}$" if mark == WORSE else f"${body}$"
    return main, "" if ci is None else f"${ci}$"


def _rows(table: pd.DataFrame, compare: str | None, cell, missing="n/a") -> list[list]:
    """The body of the table as text: per row its labels, its cells (cell(mean, std or None, interval or None,
    mark) in percent; ``missing`` without a mean) and its counts of seeds and failed jobs."""
    cols = cell_columns(table)
    marks = compare_marks(table, compare)
    has_ci = all((*c, s) in table.columns for c in cols for s in ("ci_low", "ci_high"))
    out = []
    for i, (label, row) in enumerate(table.iterrows()):
        cells = []
        for j, (n, p) in enumerate(cols):
            mean, std = row[(n, p, "mean")], row[(n, p, "std")]
            low, high = (row[(n, p, "ci_low")], row[(n, p, "ci_high")]) if has_ci else (math.nan, math.nan)
            ci = None if pd.isna(low) else f"[{100 * low:.2f}, {100 * high:.2f}]"
            cells.append(
                missing
                if pd.isna(mean)
                else cell(f"{100 * mean:.2f}", None if pd.isna(std) else f"{100 * std:.2f}", ci, marks.iloc[i, j])
            )
        out.append(_shown(_as_tuple(label)) + cells + [str(int(row[(c, "", "")])) for c in ("n_seeds", "n_failed")])
    return out


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
    return markdown_table(header, _rows(table, compare, _md_cell), table.index.nlevels) + (
        "\n" + "\n\n".join(notes) + "\n" if notes else ""
    )


TEXT_WIDTH_PT = 345.0  # LaTeX's article class at 10pt: the narrowest common text width, what to_latex fits
LATEX_SIZE = r"\footnotesize"  # the table's type; the intervals are a size smaller
LATEX_SEP_PT = 4.0  # \tabcolsep in the table (LaTeX's default: 6pt)
# widths in pt of characters in \footnotesize (Computer Modern), measured with pdflatex; others: _CHAR_PT
_CHAR_WIDTHS = {**dict.fromkeys("0123456789", 4.25), ".": 2.4, ",": 2.4, " ": 2.8, "[": 2.4, "]": 2.4, "±": 10.4}
_CHAR_WIDTHS |= {"†": 4.0, "_": 6.6, "-": 3.0, "(": 3.3, ")": 3.3, "=": 6.6}
_CHAR_PT = 4.4  # a letter, on average (upper case is wider: 6 pt)
_SCRIPT = 0.8  # \scriptsize against \footnotesize


def _tex_width(tex: str) -> float:
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
    fixed = sum(max(map(_tex_width, col)) + 2 * LATEX_SEP_PT for col in zip(*labels))
    cell = max((_tex_width(c) for row in cells for c in row), default=0.0) + 2 * LATEX_SEP_PT
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
    text. With ``caption``, a table float."""
    cols = cell_columns(table)
    names = [_tex(str(n)) for n in table.index.names]
    nl = len(names)
    levels = list(dict.fromkeys(n for n, _ in cols))
    params = list(dict.fromkeys(p for _, p in cols)) or [""]
    rows = [
        ([_tex(v) for v in r[:nl]], [(main, rf"{{\scriptsize {ci}}}" if ci else "") for main, ci in r[nl:-2]])
        for r in _rows(table, compare, _tex_cell, missing=("n/a", ""))
    ]
    per = levels_per_block or _levels_per_block(
        [names] + [labels for labels, _ in rows],
        [[t for c in cells for t in c] for _, cells in rows] + [[_tex(str(p)) for p in params]],
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
        out.append(line(names + [_tex(str(p)) for p in params] * len(block) + [""] * (pad * len(params))))
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
        body = "\n".join([r"\begin{table}", r"\centering", rf"\caption{{{_tex(caption)}}}", body + r"\end{table}"])
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
        f"{_tex(row_label(table.index.names, _as_tuple(label)))}: {s} ({f})"
        for label, s, f in zip(table.index, seeds, failed)
    )
    return f"Completed seeds (failed or unreadable jobs) per row: {per_row}."
