"""What ``hybrid-sysid-report`` writes once its arguments and paths are checked (hybrid_sysid.cli.report): the
summary table, the results pages and the runs' own figures. The command imports this module after its checks, so
a refused argument or path costs no import of the report's tables and figures (pandas, matplotlib)."""

from __future__ import annotations

import sys
from pathlib import Path

from hybrid_sysid.core.words import count
from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.paper import write_reproduction
from hybrid_sysid.report.results_page import write_results
from hybrid_sysid.report.run_figures import write_run_figures
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.runs.layout import PREDICTIONS, WRITER_LOCK
from hybrid_sysid.runs.locks import hold_for_writing


def write_report(args, command: str) -> int:
    """The summary files (unless results= alone), the results pages (results=) and each run's figures
    (run_figures=true), for the checked ``args`` of ``command``; exit status 0, or 1 when a run failed or is
    unreadable (everything is still written). ValueError or OSError when something cannot be written."""
    bad, writer = 0, None
    try:
        if args.results is None or args.out is not None:
            out = args.out or (args.paths[0] if len(args.paths) == 1 else Path("report"))
            writer = _writer_of(out, "PATH" if args.out is None else "out")
            df, table = write_summary(
                out,
                paths=args.paths,
                split=args.split,
                metric=args.metric,
                latex=args.latex,
                compare=args.compare,
                exclude=args.exclude,
            )
            print(to_markdown(table, compare=args.compare), end="")
            written = ["summary.csv", "summary.md"] + ["summary.tex"] * args.latex
            if args.reproduction:
                print("\n" + write_reproduction(out, paths=args.paths), end="")
                written.append("reproduction.md")
            runs = df.drop_duplicates("run")
            bad = int((runs.status != "completed").sum())
            print(
                f"{count(len(runs), 'run')}, {bad} failed or unreadable; wrote {out}/{', '.join(written)}, figures/",
                file=sys.stderr,
            )
        if args.results is not None:
            text, n, n_bad = write_results(
                args.results,
                args.paths,
                command=command,
                split=args.split,
                metric=args.metric,
                compare=args.compare,
                reproduction=args.reproduction,
                notes=args.notes,
                exclude=args.exclude,
                merges=args.merge,
            )
            print(text, end="")
            bad = max(bad, n_bad)
            folder = args.results.parent if args.results.suffix == ".md" else args.results
            print(
                f"{count(n, 'run')}, {n_bad} failed or unreadable; wrote {args.results} and {folder / 'figures'}/",
                file=sys.stderr,
            )
        if args.run_figures:
            drawn = draw_run_figures(args.paths, args.exclude)
            print(f"drew the figures of {count(drawn, 'run')} (figures/ in each run directory)", file=sys.stderr)
    finally:
        if writer is not None:
            writer.release()
    return 1 if bad else 0


def _writer_of(out: Path, key: str):
    """The one-writer lock of ``out`` when a run or sweep of hybrid-sysid writes there (its lock file is there),
    taken for the report's own writing: a sweep still running is refused (a table of its first jobs would race
    with its own summary, or replace it)."""
    return hold_for_writing(out, key) if (Path(out) / WRITER_LOCK).is_file() else None


def draw_run_figures(paths, exclude=()) -> int:
    """Each completed run's figures under ``paths`` (but runs matching ``exclude``); the number drawn. A run
    without predictions (e.g. a chain's parent) has nothing to draw and is skipped, with a progress line every
    ten runs on stderr."""
    root, df = load_runs(paths, exclude)
    runs = df[df.status == "completed"].drop_duplicates("run").run
    drawn = 0
    for i, name in enumerate(runs, start=1):
        if (root / name / PREDICTIONS).is_file():
            write_run_figures(root / name)
            drawn += 1
        if i % 10 == 0:
            print(f"run figures: {i} / {len(runs)} runs", file=sys.stderr, flush=True)
    return drawn
