"""``hybrid-sysid-report PATH... [key=value ...]``: rebuild a sweep's table and figures from run records.

The options are key=value, as in the other commands (``hybrid-sysid-report --help`` lists them); the former
``--key value`` flags are still accepted as aliases. Exit status: 0 if every run completed, 1 if any failed or is
unreadable (everything is still written), 2 for a bad argument (one line on stderr), a path that does not exist
or holds no runs, or compare= naming a key that is not swept.
"""

from __future__ import annotations

import shlex
import sys
from argparse import Namespace
from pathlib import Path

from hybrid_sysid.data.splits import SPLITS
from hybrid_sysid.report.collect import find_runs, load_runs
from hybrid_sysid.report.paper import write_reproduction
from hybrid_sysid.report.results_page import write_results
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import METRICS, to_markdown
from hybrid_sysid.runs.records import RECORD

PROG = "hybrid-sysid-report"
HELP = f"""{PROG}: rebuild the comparison table (summary.md, summary.csv) and figures of sweeps or runs from their
records (metrics.json), merged into one table; optionally the LaTeX table, the paper's figures beside ours, or a
results page with one section per PATH. Nothing is trained.

usage: {PROG} PATH... [key=value ...]

  PATH                  run or sweep directories (merged; a PATH that starts with a key= is written ./KEY=...)
  split=test            the split of the table and figures: {", ".join(SPLITS)}
  metric=mean_rel_dev   {", ".join(METRICS)}
  out=DIR               where to write (default: the PATH if one is given, else ./report)
  compare=KEY           the swept key whose rows the marks compare (default: objective when swept)
  exclude=GLOB          leave out runs whose name (relative to the paths' common parent) matches; repeatable,
                        e.g. exclude='*/search/*' (experiment=tuned's trials)
  latex=true            also write summary.tex (a booktabs table)
  run_figures=true      also draw each completed run's own figures (figures/ in its directory), which a sweep's
                        jobs do not draw by default
  reproduction=true     also write reproduction.md: the paper's figures beside ours (with results=: a section
                        per PATH in the page)
  results=FILE          write a results page (one section per PATH, figures in FILE's folder/figures/) instead
                        of the summary files, which are still written when out= is given
  notes=MD              with results=: a hand-written markdown file placed after the page's header
  merge=DIR,DIR,...     with results=: one more section whose table merges these sweeps ("All rows"), after the
                        section of the first DIR; repeatable. Every section names, under its heading, the command
                        that re-creates its sweeps, the commit and the CPU of their runs

Exit status: 0 every run completed; 1 some failed or are unreadable (everything is still written); 2 a bad
argument, a path without runs, or compare= naming a key that is not swept.

examples:
  {PROG} outputs/multirun/2026-01-01_12-00-00
  {PROG} outputs/multirun/a outputs/multirun/b split=val compare=objective latex=true out=report
  {PROG} outputs/multirun/tuned exclude='*/search/*' results=docs/results.md reproduction=true
"""
VALUE_KEYS = ("split", "metric", "out", "compare", "exclude", "notes", "results", "merge")
REPEATABLE = ("exclude", "merge")
FLAG_KEYS = ("latex", "reproduction", "run_figures")
KEYS = VALUE_KEYS + FLAG_KEYS


class UsageError(ValueError):
    """A bad argument: one line on stderr, exit status 2."""


def _key_values(argv: list[str]) -> list[str]:
    """The arguments with the former ``--key value``, ``--key=value`` and ``--flag`` aliases as key=value."""
    out, i = [], 0
    while i < len(argv):
        arg = argv[i]
        if arg.startswith("--"):
            key, sep, value = arg[2:].partition("=")
            if key not in KEYS:
                raise UsageError(f"unknown option {arg!r}; options are key=value: {', '.join(KEYS)} (see --help)")
            if key in FLAG_KEYS and not sep:
                value, sep = "true", "="
            elif not sep:
                if i + 1 >= len(argv):
                    raise UsageError(f"{arg} needs a value: {key}=VALUE")
                i, value = i + 1, argv[i + 1]
            arg = f"{key}={value}"
        out.append(arg)
        i += 1
    return out


def parse_args(argv) -> Namespace:
    """PATHs and key=value options -> the report's settings, each checked (UsageError)."""
    args = Namespace(paths=[], split="test", metric="mean_rel_dev", out=None, compare=None, exclude=[], merge=[])
    args.latex = args.reproduction = args.run_figures = False
    args.notes = args.results = None
    given = set()
    for arg in _key_values(list(argv)):
        key, sep, value = arg.partition("=")
        if not sep or key not in KEYS:
            if sep and key.isidentifier() and not Path(arg).exists():
                raise UsageError(f"unknown key {key!r} in {arg!r}; allowed keys: {', '.join(KEYS)}")
            args.paths.append(Path(arg))
            continue
        if key in given and key not in REPEATABLE:
            raise UsageError(f"{key} is given twice; give it once")
        given.add(key)
        if key in FLAG_KEYS:
            if value.lower() not in ("true", "false"):
                raise UsageError(f"{key} = {value!r} is not allowed: true or false")
            setattr(args, key, value.lower() == "true")
        elif key == "exclude":  # repeatable, or a list: exclude=[a,b]
            items = value[1:-1].split(",") if value.startswith("[") and value.endswith("]") else [value]
            args.exclude += [item.strip() for item in items if item.strip()]
        elif key == "merge":  # repeatable, each a group of sweeps: merge=a,b or merge=[a,b]
            items = value[1:-1] if value.startswith("[") and value.endswith("]") else value
            group = [Path(item.strip()) for item in items.split(",") if item.strip()]
            if len(group) < 2:
                raise UsageError(f"merge = {value!r} names {len(group)} sweep; give two or more: merge=DIR,DIR")
            args.merge.append(group)
        elif key == "split" and value not in SPLITS:
            raise UsageError(f"split = {value!r} is not allowed: one of {', '.join(SPLITS)}")
        elif key == "metric" and value not in METRICS:
            raise UsageError(f"metric = {value!r} is not allowed: one of {', '.join(METRICS)}")
        elif not value:
            raise UsageError(f"{key}= needs a value")
        else:
            setattr(args, key, Path(value) if key in ("out", "notes", "results") else value)
    if not args.paths:
        raise UsageError(f"no PATH given; usage: {PROG} PATH... [key=value ...] (see --help)")
    if args.merge and args.results is None:
        raise UsageError("merge= adds a section to a results page: give results=FILE too")
    return args


def _error(message: str) -> int:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    if any(a in ("-h", "--help") for a in argv):
        print(HELP, end="")
        return 0
    try:
        args = parse_args(argv)
    except UsageError as exc:
        return _error(str(exc))
    # each path must contribute, so a typo is not silently merged away
    for path in [*args.paths, *(p for group in args.merge for p in group)]:
        if not path.exists():
            return _error(f"path does not exist: {path}")
        if not find_runs([path]):
            return _error(f"no runs ({RECORD}) under {path}")
    if args.notes is not None and not args.notes.is_file():
        return _error(f"notes = {args.notes}: the file does not exist")
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
                merges=args.merge,
            )
            print(text, end="")
            bad = max(bad, n_bad)
            print(
                f"{n} runs, {n_bad} failed or unreadable; wrote {args.results} and {args.results.parent / 'figures'}/",
                file=sys.stderr,
            )
        if args.run_figures:
            drawn = draw_run_figures(args.paths, args.exclude)
            print(f"drew the figures of {drawn} runs (figures/ in each run directory)", file=sys.stderr)
    except ValueError as exc:  # e.g. compare= naming a key that is not swept
        return _error(str(exc))
    except OSError as exc:  # e.g. out= on a read-only file system: the runs themselves are untouched
        return _error(f"cannot write the report: {type(exc).__name__}: {exc}")
    return 1 if bad else 0


def draw_run_figures(paths, exclude=()) -> int:
    """Each completed run's figures under ``paths`` (but runs matching ``exclude``); the number drawn. A run
    without predictions (e.g. a chain's parent) has nothing to draw and is skipped, with a progress line every
    ten runs on stderr."""
    from hybrid_sysid.report.run_figures import write_run_figures

    root, df = load_runs(paths, exclude)
    runs = df[df.status == "completed"].drop_duplicates("run").run
    drawn = 0
    for i, name in enumerate(runs, start=1):
        if (root / name / "predictions.csv").is_file():
            write_run_figures(root / name)
            drawn += 1
        if i % 10 == 0:
            print(f"run figures: {i} / {len(runs)} runs", file=sys.stderr, flush=True)
    return drawn
