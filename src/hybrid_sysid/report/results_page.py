"""Results pages regenerated from sweep directories by one command:

    hybrid-sysid-report outputs/multirun/<robustness sweep> [more sweeps] results=docs/results

One section per sweep, and one per group of sweeps merged into one table (``merge=``): under its heading the
command that re-creates each sweep, the commit and the CPU of its runs (report/provenance.py), then its protocol
in one line, the comparison table (marks and notes as in summary.md), the robustness figure (drawn from the same
table into figures/ beside the pages), what the sweep's experiment adds (report.extras) and failed jobs; with
``reproduction``, also the paper's figures beside ours, as in reproduction.md. ``results=DIR`` writes each section
to a page of its own, ``DIR/<section>.md``, and an index, ``DIR/index.md``, that lists them and links the
hand-written reading (``notes=``); ``results=FILE.md`` writes one page that holds them all after the reading.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pandas as pd

from hybrid_sysid.core.files import ESCAPED, write_atomic
from hybrid_sysid.report import sweep_figures
from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.extras import extras_of
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.paper import LEGEND, comparison_markdown
from hybrid_sysid.report.protocol import one_line, protocol
from hybrid_sysid.report.provenance import provenance, provenance_lines
from hybrid_sysid.report.summary import bound_note, failed_lines, tested_table, windows_note
from hybrid_sysid.report.tables import METRICS

INDEX = "index.md"


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "sweep"


def _title(df: pd.DataFrame, path: Path) -> tuple[str, str]:
    """The section's title and name: 'experiment=robustness' and 'robustness' when every run of the sweep was
    launched with that experiment (its directory's name, when that differs, follows in brackets and names the
    section), else the directory's name for both."""
    title = name = path.resolve().name
    values = set(df.drop_duplicates("run").experiment) if "experiment" in df else set()
    if len(values) == 1 and "" not in values:
        experiment = values.pop()
        # two sweeps of one experiment (e.g. ablations with other overrides) keep apart by their directory names
        title = f"experiment={experiment}" + ("" if title == experiment else f" ({title})")
    return title, _slug(name)


def _sections(paths, merges) -> list[tuple[list[Path], bool]]:
    """Each path's section, each merged group right after the section of its first sweep (or at the end)."""
    merges = [[Path(p) for p in group] for group in merges]
    sections = []
    for path in map(Path, paths):
        sections.append(([path], False))
        sections += [(group, True) for group in merges if group[0].resolve() == path.resolve()]
    return sections + [(group, True) for group in merges if (group, True) not in sections]


def write_results(
    out,
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
    """Write the pages and their figures (figures/ beside them); returns (the text written: the one page, or the
    index, the number of runs, the number of failed or unreadable runs; each run counted once). ``out``: a page
    (``*.md``) or a directory of pages (the module's docstring). ``command`` is quoted as the way to regenerate
    them; ``notes``, a markdown file (the hand-written reading of the tables), is linked from the index, or on one
    page placed right after its header between two comments naming it; ``exclude``: glob patterns of run names
    left out of every table (collect.load_runs). ``merges``: groups of sweep directories, each one more section
    whose table merges them ("All rows: a, b and c"). Every section starts with its provenance."""
    out = Path(out)
    one_page = out.suffix == ".md"
    folder = out.parent if one_page else out
    if notes is not None and not Path(notes).is_file():  # before anything is written
        raise FileNotFoundError(notes)
    header = [
        f"Generated from the run records by `{command}`; run it again to regenerate "
        + ("this page" if one_page else "these pages")
        + f" (and `figures/`), do not edit by hand. Cells: {METRICS[metric]} on the {split} split, percent, "
        "mean ± sample standard deviation (ddof=1) over seeds. Under each heading: the command that re-creates "
        "its sweep, the commit its runs were made at (dirty: the working tree differed from it) and their CPU.",
        "",
    ]
    used, status, pages = set(), {}, []  # status: each run directory's, so a run in two sections counts once
    for group, merged in _sections(paths, merges):
        root, df = load_runs(group, exclude)
        status.update({root / r.run: r.status for r in df.drop_duplicates("run").itertuples()})
        names = [p.resolve().name for p in group]
        title, slug = (
            (f"All rows: {', '.join(names[:-1])} and {names[-1]}", _slug(names[0]) + "_all")
            if merged
            else _title(df, group[0])
        )
        base, i = slug, 2
        while slug in used:
            slug, i = f"{base}_{i}", i + 1
        used.add(slug)
        lines = _section(df, root, group, merged, title, slug, folder / "figures", split, metric, compare, reproduction)
        pages.append((slug, title, df, lines))
    folder.mkdir(parents=True, exist_ok=True)
    if one_page:
        text = "\n".join(["# Results", "", *header, *_notes(notes), *(line for *_, lines in pages for line in lines)])
    else:
        for slug, title, _, lines in pages:
            back = f"[Results](index.md) of `{command.split()[0]}`; cells as the index says."
            page = "\n".join([f"# Results: {title}", "", back, "", *lines]).rstrip("\n") + "\n"
            write_atomic(
                folder / f"{slug}.md", lambda p, page=page: p.write_text(page, encoding="utf-8", errors=ESCAPED)
            )
        text = "\n".join(_index(header, pages, notes, folder))
    text = text.rstrip("\n") + "\n"
    write_atomic(out if one_page else folder / INDEX, lambda p: p.write_text(text, encoding="utf-8", errors=ESCAPED))
    return text, len(status), sum(s != "completed" for s in status.values())


def _notes(notes) -> list[str]:
    """The reading on a one-page results page; the closing comment tells the generated sections from it."""
    if notes is None:
        return []
    name = Path(notes).as_posix()
    return [f"<!-- from {name} -->", Path(notes).read_text(encoding="utf-8").strip(), f"<!-- end of {name} -->", ""]


def _index(header: list[str], pages, notes, folder: Path) -> list[str]:
    lines = ["# Results", "", *header]
    if notes is not None:
        link = Path(os.path.relpath(Path(notes).resolve(), folder.resolve())).as_posix()
        lines += [f"What the tables show, read by hand: [{Path(notes).name}]({link}).", ""]
    for slug, title, df, _ in pages:
        runs = df.drop_duplicates("run")
        lines.append(f"- [{title}]({slug}.md): {len(runs)} runs, {int((runs.status == 'completed').sum())} completed")
    return lines


def _section(df, root, group, merged, title, slug, figures, split, metric, compare, reproduction) -> list[str]:
    """One section's lines: heading, provenance, protocol, table, figures, the experiment's additions, failed
    jobs, and with ``reproduction`` the paper's figures beside ours (the paper's car alone, not merges)."""
    table = tested_table(df, root, split, metric)
    n_runs, n_done = df.run.nunique(), df[df.status == "completed"].run.nunique()
    lines = [
        f"## {title}",
        "",
        *provenance_lines(provenance(df, root, group)),
        ", ".join(f"`{p}`" for p in group)
        + f": {n_runs} runs, {n_done} completed. "
        + one_line(protocol(df, root))
        + windows_note(df, table, split),
        "",
        to_markdown(table, compare=compare, bound=table.attrs.get("bound")),
        *bound_note(table.attrs.get("bound")),
    ]
    if any(c[2] == "mean" for c in table.columns):
        figures.mkdir(parents=True, exist_ok=True)
        draw = sweep_figures.robustness_figure
        if sweep_figures.fits_one_figure(table):
            write_atomic(figures / f"{slug}.png", lambda p: draw(table, p, metric=metric, split=split))
            lines += [f"![robustness: {title}]({figures.name}/{slug}.png)", ""]
        else:
            lines += [f"No robustness figure: {len(table)} rows are more lines than one figure shows apart.", ""]
        for extra in extras_of(table):  # what the experiment adds (report.extras)
            for name, figure in extra.figures.items():
                write_atomic(figures / f"{slug}_{name}.png", lambda p, figure=figure: figure(table, p))
                lines += [f"![{name}: {title}]({figures.name}/{slug}_{name}.png)", ""]
            text = extra.markdown(list(group)) if extra.markdown else ""
            lines += [text, ""] if text else []
    failed = failed_lines(df)
    if failed:
        lines += ["Failed jobs:", "", *failed, ""]
    if reproduction and not merged and all(e.paper_car for e in extras_of(table)):
        lines += ["### The paper's figures beside ours", "", comparison_markdown(df, root), LEGEND, ""]
    return lines
