"""A results page (docs/results.md) regenerated from sweep directories by one command:

    hybrid-sysid-report outputs/multirun/<robustness sweep> [more sweeps] --results docs/results.md

One section per sweep: its protocol in one line, the comparison table (marks and notes as in summary.md), the
robustness figure (drawn from the same table into figures/ next to the page) and failed jobs; with
``reproduction``, also the paper's figures beside ours and the reading of reproduction.md.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pandas as pd

from hybrid_sysid.report import sweep_figures
from hybrid_sysid.files import write_atomic
from hybrid_sysid.report.protocol import one_line, protocol
from hybrid_sysid.records import RECORD
from hybrid_sysid.report.summary import (METRICS, _collect, _resolve, failed_lines, row_keys,
                                             summary_table, to_markdown, windows_note)


def _title(df: pd.DataFrame, path: Path) -> str:
    """'experiment=robustness' when every run of the sweep was launched with that experiment, else the path's
    name."""
    if "experiment" in df:
        values = set(df.drop_duplicates("run").experiment)
        if len(values) == 1 and "" not in values:
            name = values.pop()
            # two sweeps of one experiment (e.g. ablations with other overrides) keep apart by their dir names
            return f"experiment={name}" + ("" if path.resolve().name == name else f" ({path.resolve().name})")
    return path.resolve().name


def _slug(text: str) -> str:
    text = text.removeprefix("experiment=").split(" (")[0]  # the experiment's name, without the dir suffix
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "sweep"


def write_results(file, paths, split: str = "test", metric: str = "mean_rel_dev", compare: str | None = None,
                  reproduction: bool = False, command: str | None = None,
                  notes=None) -> tuple[str, int, int]:
    """Write the page and its figures (file's folder / figures / <section>.png); returns (text, number of runs,
    number of failed or unreadable runs). ``command`` is quoted in the header as the way to regenerate the page;
    ``notes``, a markdown file (the hand-written reading of the tables), is placed right after the header."""
    file = Path(file)
    figures = file.parent / "figures"
    paths = [Path(p) for p in paths]
    command = command or "hybrid-sysid-report " + " ".join(shlex.quote(str(p)) for p in paths) + \
        f" --results {shlex.quote(str(file))}" + (" --reproduction" if reproduction else "")
    lines = ["# Results", "",
             f"Generated from the run records by `{command}`; run it again to regenerate this page (and "
             f"`{figures.name}/`), do not edit by hand. Cells: {METRICS[metric]} on the {split} split, percent, "
             "mean ± sample standard deviation (ddof=1) over seeds.", ""]
    if notes is not None:  # read first: a missing file fails before anything is written
        lines += [f"<!-- from {Path(notes).as_posix()} -->", Path(notes).read_text(encoding="utf-8").strip(), ""]
    n_all, n_bad, used = 0, 0, set()
    for path in paths:
        root, runs = _resolve([path])
        if not runs:
            raise ValueError(f"{path} holds no run ({RECORD})")
        df = _collect(root, runs)
        table = summary_table(df, split=split, metric=metric)
        title = _title(df, path)
        slug, i = _slug(title), 2
        while slug in used:
            slug, i = f"{_slug(title)}_{i}", i + 1
        used.add(slug)
        n_runs, n_done = df.run.nunique(), df[df.status == "completed"].run.nunique()
        n_all, n_bad = n_all + n_runs, n_bad + n_runs - n_done
        lines += [f"## {title}", "",
                  f"`{path}`: {n_runs} runs, {n_done} completed. " + one_line(protocol(df, root))
                  + windows_note(df, table, split), "", to_markdown(table, compare=compare)]
        if any(c[2] == "mean" for c in table.columns):
            figures.mkdir(parents=True, exist_ok=True)
            write_atomic(figures / f"{slug}.png",
                          lambda p: sweep_figures.robustness_figure(table, p, metric=metric, split=split))
            lines += [f"![robustness: {title}]({figures.name}/{slug}.png)", ""]
        failed = failed_lines(df, row_keys(df))
        if failed:
            lines += ["Failed jobs:", "", *failed, ""]
        if reproduction:
            from hybrid_sysid.report.paper import LEGEND, comparison_parts

            table_md, reading = comparison_parts(df, root)
            lines += ["### The paper's figures beside ours", "", table_md, LEGEND, "", reading, ""]
    text = "\n".join(lines).rstrip("\n") + "\n"
    file.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(file, lambda p: p.write_text(text, encoding="utf-8"))
    return text, n_all, n_bad
