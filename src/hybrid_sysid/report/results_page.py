"""A results page (docs/results.md) regenerated from sweep directories by one command:

    hybrid-sysid-report outputs/multirun/<robustness sweep> [more sweeps] --results docs/results.md

One section per sweep, and one per group of sweeps merged into one table (``merge=``): under its heading the
command that re-creates each sweep, the commit and the CPU of its runs (report/provenance.py), then its protocol
in one line, the comparison table (marks and notes as in summary.md), the robustness figure (drawn from the same
table into figures/ next to the page) and failed jobs; with ``reproduction``, also the paper's figures beside
ours, as in reproduction.md.
"""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd

from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.report import sweep_figures
from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.extras import extras_of
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.paper import LEGEND, comparison_markdown
from hybrid_sysid.report.protocol import one_line, protocol
from hybrid_sysid.report.provenance import provenance, provenance_lines
from hybrid_sysid.report.summary import failed_lines, tested_table, windows_note
from hybrid_sysid.report.tables import METRICS


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
    merges=(),
) -> tuple[str, int, int]:
    """Write the page and its figures (file's folder / figures / <section>.png); returns (text, number of runs,
    number of failed or unreadable runs; each run counted once). ``command`` is quoted in the header as the way to
    regenerate the page; ``notes``, a markdown file (the hand-written reading of the tables), is placed right after
    the header, between two comments naming it; ``exclude``: glob patterns of run names left out of every table
    (collect.load_runs). ``merges``: groups of sweep directories, each one more section whose table merges them
    ("All rows: a, b and c"), placed right after the section of its first sweep when that is one of ``paths``,
    else at the end. Every section starts with its provenance (report/provenance.py)."""
    file = Path(file)
    figures = file.parent / "figures"
    lines = [
        "# Results",
        "",
        f"Generated from the run records by `{command}`; run it again to regenerate this page (and "
        f"`{figures.name}/`), do not edit by hand. Cells: {METRICS[metric]} on the {split} split, percent, "
        "mean ± sample standard deviation (ddof=1) over seeds. Under each heading: the command that re-creates "
        "its sweep, the commit its runs were made at (dirty: the working tree differed from it) and their CPU.",
        "",
    ]
    if notes is not None:  # read first: a missing file fails before anything is written
        name = Path(notes).as_posix()
        # the closing comment tells the generated sections from the hand-written ones (a test checks the former)
        lines += [
            f"<!-- from {name} -->",
            Path(notes).read_text(encoding="utf-8").strip(),
            f"<!-- end of {name} -->",
            "",
        ]
    # the sections: each path's, each merged group right after the section of its first sweep (or at the end)
    merges = [[Path(p) for p in group] for group in merges]
    sections = []
    for path in map(Path, paths):
        sections.append(([path], False))
        sections += [(group, True) for group in merges if group[0].resolve() == path.resolve()]
    sections += [(group, True) for group in merges if (group, True) not in sections]
    used, status = set(), {}  # status: each run directory's, so a run in two sections counts once
    for group, merged in sections:
        root, df = load_runs(group, exclude)
        status.update({root / r.run: r.status for r in df.drop_duplicates("run").itertuples()})
        table = tested_table(df, root, split, metric)
        names = [p.resolve().name for p in group]
        title, slug = (
            (f"All rows: {', '.join(names[:-1])} and {names[-1]}", re.sub(r"[^A-Za-z0-9_.-]+", "_", names[0]) + "_all")
            if merged
            else _title(df, group[0])
        )
        base, i = slug, 2
        while slug in used:
            slug, i = f"{base}_{i}", i + 1
        used.add(slug)
        n_runs, n_done = df.run.nunique(), df[df.status == "completed"].run.nunique()
        lines += [
            f"## {title}",
            "",
            *provenance_lines(provenance(df, root, group)),
            ", ".join(f"`{p}`" for p in group)
            + f": {n_runs} runs, {n_done} completed. "
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
            for extra in extras_of(table):  # what the experiment adds (report.extras)
                for name, draw in extra.figures.items():
                    write_atomic(figures / f"{slug}_{name}.png", lambda p, draw=draw, table=table: draw(table, p))
                    lines += [f"![{name}: {title}]({figures.name}/{slug}_{name}.png)", ""]
                text = extra.markdown(list(group)) if extra.markdown else ""
                lines += [text, ""] if text else []
        failed = failed_lines(df)
        if failed:
            lines += ["Failed jobs:", "", *failed, ""]
        # the paper reports the paper's car only; the comparison goes with a sweep's own section, not its merges
        if reproduction and not merged and all(e.paper_car for e in extras_of(table)):
            lines += ["### The paper's figures beside ours", "", comparison_markdown(df, root), LEGEND, ""]
    text = "\n".join(lines).rstrip("\n") + "\n"
    file.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(file, lambda p: p.write_text(text, encoding="utf-8"))
    return text, len(status), sum(s != "completed" for s in status.values())
