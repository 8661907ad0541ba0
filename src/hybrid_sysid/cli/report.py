"""hybrid-sysid-report PATH...: rebuild a sweep's summary files and figures from run or sweep directories
(merged), and with --reproduction the paper's figures beside ours; with --results, a results page instead (one
section per PATH). Exit code: 0 if every run completed, 1 if any failed or is unreadable (everything is still
written), 2 if a path does not exist or holds no runs, or --compare names a key that is not swept."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from hybrid_sysid.data.splits import SPLITS
from hybrid_sysid.report.collect import find_runs
from hybrid_sysid.report.paper import write_reproduction
from hybrid_sysid.report.results_page import write_results
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import METRICS, to_markdown
from hybrid_sysid.runs.records import RECORD

PROG = "hybrid-sysid-report"


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Rebuild the sweep tables and figures from run or sweep "
        "directories (merged). Exit 0: all runs completed; 1: some failed; 2: bad path.",
    )
    p.add_argument("paths", nargs="+", type=Path, metavar="PATH", help="run or sweep directories (merged)")
    p.add_argument(
        "--split", default="test", choices=list(SPLITS), help="split of the table and figures (default: test)"
    )
    p.add_argument("--metric", default="mean_rel_dev", choices=list(METRICS), help="default: mean_rel_dev")
    p.add_argument(
        "--out", type=Path, default=None, help="output directory (default: the PATH if one is given, else ./report)"
    )
    p.add_argument(
        "--compare",
        default=None,
        metavar="KEY",
        help="the swept key whose rows the marks compare (default: objective when swept)",
    )
    p.add_argument(
        "--exclude",
        action="append",
        default=[],
        metavar="GLOB",
        help="leave out the runs whose name relative to the paths' common parent matches (repeatable), "
        "e.g. '*/search/*': experiment=tuned's trials",
    )
    p.add_argument("--latex", action="store_true", help="also write summary.tex (a booktabs table)")
    p.add_argument(
        "--reproduction",
        action="store_true",
        help="also write reproduction.md: the paper's figures beside ours and both protocols "
        "(with --results: a section per PATH in the page)",
    )
    p.add_argument(
        "--notes",
        type=Path,
        default=None,
        metavar="MD",
        help="with --results: a hand-written markdown file (the reading of the tables) placed after the page's header",
    )
    p.add_argument(
        "--results",
        type=Path,
        default=None,
        metavar="FILE",
        help="write a results page (one section per PATH: table, figure in FILE's folder/figures/) "
        "instead of the summary files, which are still written when --out is given",
    )
    return p.parse_args(argv)


def _error(message: str) -> int:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    args = parse_args(argv)
    for path in args.paths:  # each path must contribute, so a typo is not silently merged away
        if not path.exists():
            return _error(f"path does not exist: {path}")
        if not find_runs([path]):
            return _error(f"no runs ({RECORD}) under {path}")
    if args.notes is not None and not args.notes.is_file():
        return _error(f"--notes file does not exist: {args.notes}")
    bad = 0
    try:
        if args.results is None or args.out is not None:
            out = args.out or (args.paths[0] if len(args.paths) == 1 else Path("report"))
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
                f"{len(runs)} runs, {bad} failed or unreadable; wrote {out}/{', '.join(written)}, figures/",
                file=sys.stderr,
            )
        if args.results is not None:
            text, n, n_bad = write_results(
                args.results,
                args.paths,
                command=shlex.join([PROG, *argv]),
                split=args.split,
                metric=args.metric,
                compare=args.compare,
                reproduction=args.reproduction,
                notes=args.notes,
                exclude=args.exclude,
            )
            print(text, end="")
            bad = max(bad, n_bad)
            print(
                f"{n} runs, {n_bad} failed or unreadable; wrote {args.results} and {args.results.parent / 'figures'}/",
                file=sys.stderr,
            )
    except ValueError as exc:  # e.g. --compare naming a key that is not swept
        return _error(str(exc))
    except OSError as exc:  # e.g. --out on a read-only file system: the runs themselves are untouched
        return _error(f"cannot write the report: {type(exc).__name__}: {exc}")
    return 1 if bad else 0
