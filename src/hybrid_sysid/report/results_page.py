"""A results page (docs/results.md) regenerated from sweep directories by one command:

    hybrid-sysid-report outputs/multirun/<robustness sweep> [more sweeps] --results docs/results.md

One section per sweep: its protocol in one line, the comparison table (marks and notes as in summary.md), the
robustness figure (drawn from the same table into figures/ next to the page) and failed jobs; with
``reproduction``, also the paper's figures beside ours, as in reproduction.md.
"""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd

from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.report import sweep_figures
from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.paper import LEGEND, comparison_markdown
from hybrid_sysid.report.protocol import one_line, protocol
from hybrid_sysid.report.summary import failed_lines, tested_table, windows_note
from hybrid_sysid.report.tables import METRICS, to_markdown
from hybrid_sysid.report.tuning import tuning_markdown


def _title(df: pd.DataFrame, path: Path) -> tuple[str, str]:
    """The section's title and figure name: 'experiment=robustness' and 'robustness' when every run of the sweep
    was launched with that experiment, else the directory's name for both."""
    title = name = path.resolve().name
    values = set(df.drop_duplicates("run").experiment) if "experiment" in df else set()
    if len(values) == 1 and "" not in values:
        name = values.pop()
        # two sweeps of one experiment (e.g. ablations with other overrides) keep apart by their directory names
        title = f"experiment={name}" + ("" if title == name else f" ({title})")
    return title, re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "sweep"


def write_results(
    file,
    paths,
    command: str,
    split: str = "test",
    metric: str = "mean_rel_dev",
    compare: str | None = None,
    reproduction: bool = False,
    notes=None,
    exclude=(),
) -> tuple[str, int, int]:
    """Write the page and its figures (file's folder / figures / <section>.png); returns (text, number of runs,
    number of failed or unreadable runs). ``command`` is quoted in the header as the way to regenerate the page;
    ``notes``, a markdown file (the hand-written reading of the tables), is placed right after the header;
    ``exclude``: glob patterns of run names left out of every table (collect.load_runs)."""
    file = Path(file)
    figures = file.parent / "figures"
    lines = [
        "# Results",
        "",
        f"Generated from the run records by `{command}`; run it again to regenerate this page (and "
        f"`{figures.name}/`), do not edit by hand. Cells: {METRICS[metric]} on the {split} split, percent, "
        "mean ± sample standard deviation (ddof=1) over seeds.",
        "",
    ]
    if notes is not None:  # read first: a missing file fails before anything is written
        lines += [f"<!-- from {Path(notes).as_posix()} -->", Path(notes).read_text(encoding="utf-8").strip(), ""]
    n_all, n_bad, used = 0, 0, set()
    for path in map(Path, paths):
        root, df = load_runs(path, exclude)
        table = tested_table(df, root, split, metric)
        title, slug = _title(df, path)
        base, i = slug, 2
        while slug in used:
            slug, i = f"{base}_{i}", i + 1
        used.add(slug)
        n_runs, n_done = df.run.nunique(), df[df.status == "completed"].run.nunique()
        n_all, n_bad = n_all + n_runs, n_bad + n_runs - n_done
        lines += [
            f"## {title}",
            "",
            f"`{path}`: {n_runs} runs, {n_done} completed. "
            + one_line(protocol(df, root))
            + windows_note(df, table, split),
            "",
            to_markdown(table, compare=compare),
        ]
        if any(c[2] == "mean" for c in table.columns):
            figures.mkdir(parents=True, exist_ok=True)
            write_atomic(
                figures / f"{slug}.png",
                lambda p, table=table: sweep_figures.robustness_figure(table, p, metric=metric, split=split),
            )
            lines += [f"![robustness: {title}]({figures.name}/{slug}.png)", ""]
            if "scenario" in table.index.names:  # experiment=transfer: the bars of its rows per scenario
                write_atomic(
                    figures / f"{slug}_bars.png", lambda p, table=table: sweep_figures.transfer_figure(table, p)
                )
                lines += [f"![transfer: {title}]({figures.name}/{slug}_bars.png)", ""]
            if "tuning" in table.index.names:  # experiment=tuned: default against tuned, and each search
                write_atomic(
                    figures / f"{slug}_tuning.png", lambda p, table=table: sweep_figures.tuning_figure(table, p)
                )
                lines += [f"![tuning: {title}]({figures.name}/{slug}_tuning.png)", "", tuning_markdown(path), ""]
        failed = failed_lines(df)
        if failed:
            lines += ["Failed jobs:", "", *failed, ""]
        if reproduction and "scenario" not in table.index.names:  # the paper reports the paper's car only
            lines += ["### The paper's figures beside ours", "", comparison_markdown(df, root), LEGEND, ""]
    text = "\n".join(lines).rstrip("\n") + "\n"
    file.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(file, lambda p: p.write_text(text, encoding="utf-8"))
    return text, n_all, n_bad
