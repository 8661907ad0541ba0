"""What experiment=tuned adds to its table's report (report.extras): a table of each job's search (the validation
figure of its default values, trial 0, and of its best trial, and the best values: hybrid_sysid.experiments.tuned
writes them to <job>/search/best.yaml), and a figure of default against tuned rows."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from hybrid_sysid.report.markdown import markdown_table
from hybrid_sysid.report.plotting import figure_legend, noise_axis, panels, save_figure
from hybrid_sysid.report.stats import K_LEVEL
from hybrid_sysid.report.sweep_figures import draw_rows, row_dicts
from hybrid_sysid.report.tables import METRICS
from hybrid_sysid.runs.reading import read_yaml

TUNING = "tuning"  # the row key of its sub-runs: default or tuned


def searches(paths) -> list[tuple[str, dict]]:
    """(job directory, best.yaml) for every search at or below paths, in path order."""
    paths = [Path(paths)] if isinstance(paths, (str, Path)) else [Path(p) for p in paths]
    found = sorted({f.resolve() for p in paths for f in p.rglob("search/best.yaml")})
    return [(f.parent.parent.name, read_yaml(f) or {}) for f in found]


def _g(value) -> str:
    return "n/a" if value is None else f"{value:.4g}" if isinstance(value, float) else str(value)


def tuning_markdown(paths) -> str:
    """A markdown table of the searches; the job's own overrides (those not shared by every job) label its row.
    An empty string when there is none."""
    found = searches(paths)
    if not found:
        return ""
    shared = set.intersection(*(set(b.get("overrides") or []) for _, b in found))
    params = list(dict.fromkeys(k for _, b in found for k in b["best"]["params"]))
    header = ["job", "monitor", "trials", "default (trial 0)", "best", "best trial", *params]
    rows = []
    for job, b in found:
        label = " ".join(o for o in b.get("overrides") or [] if o not in shared) or job
        rows.append(
            [
                label,
                b.get("monitor", ""),
                f"{b['completed']}/{b['n_trials']}",
                _g(b["default"]["value"]),
                _g(b["best"]["value"]),
                str(b["best"]["trial"]),
                *(_g(b["best"]["params"].get(k)) for k in params),
            ]
        )
    return (
        "Searches: the validation figure each objective's model selection uses (lower is better), of its "
        "default values and of its best trial, and the best trial's values.\n\n"
        + markdown_table(header, rows, n_left=2)
    )


def tuning_figure(table: pd.DataFrame, path: Path, k: int = 1, metric: str = "mean_rel_dev") -> None:
    """experiment=tuned: the metric in percent against noise std, one colour per objective, dashed with its
    default values and solid with its tuned ones, one panel per parameter, at one K; error bars: std over seeds.
    ``table`` has the row levels objective and tuning (and K when several were evaluated)."""
    if K_LEVEL in table.index.names:
        table = table.xs(k, level=K_LEVEL)
    cells = [c for c in table.columns if c[2] == "mean"]
    params = sorted({p for _, p, _ in cells})
    levels = sorted({n for n, _, _ in cells})
    # with one objective swept it is no row level: one colour
    rows = [{"objective": "", **r} for r in row_dicts(table)]
    colours = {o: f"C{i}" for i, o in enumerate(dict.fromkeys(r["objective"] for r in rows))}
    styles = [(colours[r["objective"]], "--" if r["tuning"] == "default" else "-") for r in rows]
    labels = [", ".join(v for v in (r["objective"], r["tuning"]) if v) for r in rows]
    fig, axes = panels(len(params))
    for ax, param in zip(axes[0], params):
        draw_rows(ax, table, param, levels, styles, labels)
        noise_axis(ax, levels, METRICS[metric], param)
    figure_legend(fig)
    save_figure(fig, path, f"tuning: test split, K = {k}, mean ± std over seeds (dashed: default values)")
