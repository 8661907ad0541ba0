"""The comparison table of a sweep: mean ± seed spread and a confidence interval per cell, the best row marked,
and whether each other row is worse than it (statistics: stats.py); written as GitHub markdown (markdown.py) and
LaTeX (latex.py).

The spread over seeds is the sample standard deviation (ddof=1); the interval is the 95% Student t interval of
the mean over seeds (scipy.stats.t; seeds are the independent repetitions, and with 3 of them it is wide). With a
single seed neither is shown. The marks (the rule is printed under every table): in each column, among rows
that differ only in the compared key (``objective`` when it is swept, or the key an experiment's additions
name: report/extras.py), the lowest mean is **bold**. Where a row
and the bold row share their test recordings and the per-recording predictions are at hand (``paired``), a row is
marked † when a two-sided Wilcoxon signed-rank test (scipy.stats.wilcoxon) on the per-recording relative
deviations, averaged over seeds, finds a difference at p < 0.05; otherwise when its gap to the bold row is larger
than the combined seed spread, |m_a - m_b| > s_a + s_b (rows with fewer than two seeds are then never marked).
Lower is better: both metrics are errors.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from hybrid_sysid.core.checks import bad
from hybrid_sysid.core.options import METRICS
from hybrid_sysid.report.collect import natural_key, row_keys
from hybrid_sysid.report.stats import ALPHA, CONFIDENCE, K_LEVEL, NO_KEYS, paired_p, t_interval

BEST, WORSE, WITHIN, UNKNOWN = "best", "worse", "within", "unknown"
DAGGER = "†"
MIN_SEEDS = 3  # rows with fewer completed seeds get a warning under the table


def summary_table(df: pd.DataFrame, split: str = "test", metric: str = "mean_rel_dev") -> pd.DataFrame:
    """From collect's long form. Rows: the swept values other than seed ("all" if none vary), plus a level "K"
    when rows sharing those values hold more than one windows value. Columns (noise_std, parameter, stat): stat
    "mean", "std" (ddof=1), "ci_low" and "ci_high" (t_interval) of the metric over the completed seeds; then
    ("n_seeds", "", "") counting completed
    runs (with a K level: completed runs with results at that K) and ("n_failed", "", "") counting the others."""
    if metric not in METRICS:
        bad("metric", metric, f"one of {', '.join(METRICS)}")
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
        index = pd.MultiIndex.from_tuples([(*as_tuple(c), k) for c in counts.index for k in ks], names=rows)
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


class Shared(dict):
    """A dict kept in a table's attrs that pandas shares instead of copying: pandas deep-copies attrs into the
    result of every operation on the table, and with one frame of per-recording deviations per row (80 rows in
    experiment=anchored) that copying took two thirds of the report's time. Its frames are only read."""

    def __deepcopy__(self, memo) -> "Shared":
        return self


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
    out = Shared()
    for label, frame in mean.groupby(level=rows if len(rows) > 1 else rows[0]):
        out[label] = frame.droplevel(rows)
    return out


def as_tuple(label) -> tuple:
    return label if isinstance(label, tuple) else (label,)


def cell_columns(table: pd.DataFrame) -> list[tuple]:
    """The (noise_std, parameter) pairs that have a "mean" column, in table order."""
    return [c[:2] for c in table.columns if c[2] == "mean"]


def compared_level(table: pd.DataFrame, compare: str | None = None) -> str | None:
    """The index level whose values are compared: ``compare`` if given, else ``objective`` when it is a level,
    else the one an experiment's additions name (report/extras.py, in attrs["extras"]: report.summary.tested_table)
    when it is one, else the first level that is not K. None for the single "all" row."""
    names = [str(n) for n in table.index.names]
    if compare is not None:
        if compare not in names:
            bad("compare", compare, f"a row key of the table: {', '.join(names)}")
        return compare
    for preferred in ("objective", *(e.compare for e in table.attrs.get("extras", ()) if e.compare)):
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
                p = None if r == best else paired_p(paired, table.index[r], table.index[best], col)
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
    return ", ".join(f"{n}={v}" for n, v in zip(names, shown(values))) or NO_KEYS


def shown(values) -> list[str]:
    return [str(v) if v != "" else "(default)" for v in values]


def tex(s: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    out = s.replace("\\", "\0")
    for a in "_%&#${}":
        out = out.replace(a, "\\" + a)
    return out.replace("\0", r"\textbackslash{}").replace("±", r"$\pm$")


def legend(table: pd.DataFrame, compare: str | None = None, latex: bool = False) -> list[str]:
    """The lines under a table: the interval, the marking rule (and which test made the marks), and a warning
    for rows with fewer than MIN_SEEDS seeds."""
    esc = tex if latex else str
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
            f"[a, b]: {CONFIDENCE:.0%} Student t interval of the mean over seeds, cut at 0.".replace(
                "%", r"\%" if latex else "%"
            )
        )
    few = [(label, int(n)) for label, n in table[("n_seeds", "", "")].items() if n < MIN_SEEDS]
    if few:
        lines.append(
            f"Warning: fewer than {MIN_SEEDS} seeds in "
            + "; ".join(f"{esc(row_label(table.index.names, as_tuple(label)))} ({n})" for label, n in few)
            + ": the spread over seeds is unreliable there."
        )
    return lines


def cell_rows(table: pd.DataFrame, compare: str | None, cell, missing="n/a") -> list[list]:
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
        out.append(shown(as_tuple(label)) + cells + [str(int(row[(c, "", "")])) for c in ("n_seeds", "n_failed")])
    return out


BOUND_LABEL = "Cramér-Rao bound"


def bound_table(df: pd.DataFrame, split: str = "test", column: str = "bound") -> pd.DataFrame:
    """The Cramér-Rao bound of collect's long form: the expected mean relative deviation of an efficient unbiased
    estimator on the split's windows (model.metrics.bound_fields), averaged over the completed runs that recorded
    it (each seed scores its own seeded windows). Rows: K; columns (noise_std, parameter). Empty when no run
    recorded a bound (baselines and networks alike record it; older records do not)."""
    if column not in df.columns:
        return pd.DataFrame()
    sub = df[(df.status == "completed") & (df.split == split)].dropna(subset=[column])
    if sub.empty:
        return pd.DataFrame()
    return sub.groupby(["windows", "noise_std", "parameter"])[column].mean().unstack(["noise_std", "parameter"])
