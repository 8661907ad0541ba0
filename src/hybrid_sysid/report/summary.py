"""A sweep's summary files, built from its run records on disk alone: summary.csv (collect's long form),
summary.md (the comparison table and the failed jobs), summary.tex on request, figures/, and what an experiment
adds to its table (report.extras: its figures, a section in words as <row key>.md)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from hybrid_sysid.core.files import ESCAPED, write_atomic
from hybrid_sysid.report import sweep_figures
from hybrid_sysid.report.collect import load_predictions, load_runs, row_keys
from hybrid_sysid.report.extras import extras_for, extras_of
from hybrid_sysid.report.latex import to_latex
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.stats import K_LEVEL
from hybrid_sysid.report.tables import (
    BOUND_LABEL,
    METRICS,
    bound_table,
    compared_level,
    paired_deviations,
    row_label,
    summary_table,
)
from hybrid_sysid.runs.layout import CURVES, FIGURES
from hybrid_sysid.runs.rundir import RunDir


def windows_note(df: pd.DataFrame, table: pd.DataFrame, split: str) -> str:
    """A sentence naming K when every row of the split uses the same K other than 1 (the table then has no K
    level to show it), else an empty string."""
    if K_LEVEL in table.index.names:
        return ""
    ks = df[(df.status == "completed") & (df.split == split)].windows.dropna().unique()
    return f" Windows averaged per recording: K = {int(ks[0])}." if len(ks) == 1 and ks[0] != 1 else ""


def threads_warning(df: pd.DataFrame) -> str:
    """A warning when the completed runs used different torch thread counts (their numbers then differ beyond
    rounding: docs/reliability/reproducibility.md), else an empty string."""
    done = df[df.status == "completed"].drop_duplicates("run")
    counts = sorted(int(n) for n in done["threads"].dropna().unique()) if "threads" in done else []
    if len(counts) < 2:
        return ""
    return (
        f"Warning: the runs used different torch thread counts ({', '.join(map(str, counts))}); the same "
        "config gives slightly different numbers with other thread counts (set trainer.threads)."
    )


def failed_lines(df: pd.DataFrame) -> list[str]:
    """One markdown list item per failed or unreadable job (its swept values and seed, status and error)."""
    keys, lines = row_keys(df), []
    for _, r in df.drop_duplicates("run").query("status != 'completed'").iterrows():
        config = ", ".join(
            [f"{k}={r[k]}" for k in keys if r[k] != ""] + ([f"seed={r.seed}"] if pd.notna(r.seed) else [])
        )
        error = " ".join(str(r.error).split()) if pd.notna(r.error) else "no error recorded"
        lines.append(f"- `{r.run}` ({config}): {r.status}: {error}")
    return lines


def _curves(df: pd.DataFrame, root: Path) -> pd.DataFrame:
    """Each completed run's curves.csv, labelled by its table row; a missing or corrupt file is skipped."""
    keys, frames = row_keys(df), []
    for _, r in df[df.status == "completed"].drop_duplicates("run").iterrows():
        try:
            c = RunDir(root / r.run).read_table(CURVES)
        except (OSError, ValueError):
            continue
        frames.append(c.assign(run=r.run, label=row_label(keys, [r[k] for k in keys])))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def tested_table(df: pd.DataFrame, root: Path, split: str = "test", metric: str = "mean_rel_dev") -> pd.DataFrame:
    """summary_table of collect's long form, with attrs["paired"]: the per-recording deviations its marks test
    (tables.paired_deviations; read from the runs' predictions.csv under root) when the metric is
    mean_rel_dev, and attrs["extras"]: what the runs' experiment adds (report.extras)."""
    table = summary_table(df, split=split, metric=metric)
    table.attrs["extras"] = extras_for(df, table)
    if metric == "mean_rel_dev":
        table.attrs["paired"] = paired_deviations(load_predictions(root, df, split), df, table)
        table.attrs["bound"] = bound_table(df, split)  # the robustness figure's dashed line
    return table


def reference_note(df: pd.DataFrame, split: str) -> list[str]:
    """Which runs' deviations are not from true values: runs on a user's recordings without labels measure each
    estimate against a fit (the record's ``reference``), and the table must say so."""
    if "reference" not in df:
        return []
    rows = df[(df.status == "completed") & (df.split == split) & (df.reference.fillna("labels") != "labels")]
    if rows.empty:
        return []
    runs = rows.drop_duplicates("run")
    names = ", ".join(f"`{r}`" for r in runs.run[:5]) + (", ..." if len(runs) > 5 else "")
    refs = " / ".join(sorted(set(runs.reference)))
    return [f"Deviations from the {refs}, not from true values (recordings without labels): {names}.", ""]


def bound_note(bound) -> list[str]:
    """What the table's Cramér-Rao bound row means (markdown.bound_rows), when it has one."""
    if bound is None or bound.empty:
        return []
    return [
        f"{BOUND_LABEL}: the mean relative deviation an efficient unbiased estimator is expected to reach on these "
        "test windows at each noise level (both channels noisy; the true input and the window's transient unknown; "
        "model.metrics.bound_fields). An estimator below it draws on prior knowledge: a training set or a prior.",
        "",
    ]


def write_summary(
    sweep_dir,
    paths=None,
    split: str = "test",
    metric: str = "mean_rel_dev",
    figures: bool = True,
    latex: bool = False,
    compare: str | None = None,
    exclude=(),
    on_table=None,
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Write sweep_dir/summary.csv, summary.md, with ``latex`` summary.tex, and figures/ from the runs at or
    below paths (default: sweep_dir), but those whose name (relative to the common parent, e.g. "0/search/3")
    matches a glob pattern of ``exclude``. ``compare``: the row key whose values the marks compare (default:
    objective when swept). Returns (long form, table); the table's attrs["paired"] holds the per-recording
    deviations its marks test (tables.paired_deviations), attrs["sections"] the sections in words an experiment
    adds (report.extras).
    ``on_table(df, table)`` is called once the summary files are written, before the figures are drawn (a sweep
    prints its table there)."""
    sweep_dir = Path(sweep_dir)
    root, df = load_runs(sweep_dir if paths is None else paths, exclude)
    table = tested_table(df, root, split, metric)
    compared_level(table, compare)  # a bad compare key fails before anything is written
    runs = df.drop_duplicates("run")
    n_bad = int((runs.status != "completed").sum())
    md = [
        f"# Sweep summary: {METRICS[metric]} on the {split} split [%]",
        "",
        f"{len(runs)} runs: {len(runs) - n_bad} completed, {n_bad} failed or unreadable. Cells: mean ± sample "
        f"standard deviation (ddof=1) over seeds, [95% t interval].{windows_note(df, table, split)}",
        "",
        to_markdown(table, compare=compare, bound=table.attrs.get("bound")),
        *bound_note(table.attrs.get("bound")),
        *reference_note(df, split),
        *([threads_warning(df), ""] if threads_warning(df) else []),
        "## Failed jobs",
        "",
        *(failed_lines(df) or ["None."]),
    ]
    sweep_dir.mkdir(parents=True, exist_ok=True)
    write_atomic(sweep_dir / "summary.csv", lambda p: df.to_csv(p, index=False, errors=ESCAPED))
    write_atomic(
        sweep_dir / "summary.md", lambda p: p.write_text("\n".join(md) + "\n", encoding="utf-8", errors=ESCAPED)
    )
    if latex:
        caption = f"{METRICS[metric]} on the {split} split [%], mean ± std over seeds"
        write_atomic(
            sweep_dir / "summary.tex",
            lambda p: p.write_text(to_latex(table, compare=compare, caption=caption), encoding="utf-8", errors=ESCAPED),
        )
    if on_table is not None:
        on_table(df, table)
    sections = table.attrs["sections"] = []
    for extra in extras_of(table):  # what the experiment adds (report.extras)
        text = extra.markdown([sweep_dir] if paths is None else list(paths)) if extra.markdown else ""
        if text:
            write_atomic(
                sweep_dir / f"{extra.row_key}.md",
                lambda p, text=text: p.write_text(text, encoding="utf-8", errors=ESCAPED),
            )
            sections.append(text)
    if figures:
        out = sweep_dir / FIGURES
        out.mkdir(exist_ok=True)
        if any(c[2] == "mean" for c in table.columns):
            for extra in extras_of(table):
                for name, draw in extra.figures.items():
                    write_atomic(out / f"{name}.png", lambda p, draw=draw: draw(table, p))
        # at least one completed run, and few enough rows for one legible figure
        if any(c[2] == "mean" for c in table.columns) and sweep_figures.fits_one_figure(table):
            write_atomic(
                out / "robustness.png", lambda p: sweep_figures.robustness_figure(table, p, metric=metric, split=split)
            )
        curves = _curves(df, root)
        # runs record curves on train and test only: other splits fall back to test
        on = split if len(curves) and (curves["split"] == split).any() else "test"
        if len(curves) and (curves["split"] == on).any():
            write_atomic(
                out / "learning_curves_compared.png",
                lambda p: sweep_figures.learning_curves_compared(curves, p, metric=metric, split=on),
            )
    return df, table
