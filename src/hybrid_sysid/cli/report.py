"""``hybrid-sysid-report PATH... [key=value ...]``: rebuild a sweep's table and figures from run records.

The options are key=value, as in the other commands (``hybrid-sysid-report --help`` lists them; the parser is
hybrid_sysid.cli.arguments, which hybrid-sysid-predict shares). Exit status: 0 if every run completed, 1 if any
failed or is unreadable (everything is still written), 2 for a bad argument (one line on stderr), a path that
does not exist or holds no runs, or compare= naming a key that is not swept.
"""

from __future__ import annotations

import shlex
import signal
import sys
from argparse import Namespace
from pathlib import Path

from hybrid_sysid.cli.arguments import Key, UsageError, parse
from hybrid_sysid.core.checks import Shown
from hybrid_sysid.core.options import METRICS
from hybrid_sysid.core.stop import Interrupted
from hybrid_sysid.data.splits import SPLITS
from hybrid_sysid.launch.console import tolerant_streams
from hybrid_sysid.runs.layout import RECORD, check_outside_runs
from hybrid_sysid.runs.reading import find_runs

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
  reproduction=true     also write reproduction.md: the paper's figures beside ours (with results=: in each
                        section of the results)
  results=DIR           write results pages instead of the summary files (which out= still writes): DIR/index.md
                        and a page per PATH, DIR/<section>.md, figures in DIR/figures/; results=FILE.md writes
                        one page holding every section
  notes=MD              with results=: the hand-written reading, linked from the index (on one page: placed
                        after its header)
  merge=DIR,DIR,...     with results=: one more section whose table merges these sweeps ("All rows"), after the
                        section of the first DIR; repeatable. Every section names, under its heading, the command
                        that re-creates its sweeps, the commit and the CPU of their runs

Exit status: 0 every run completed; 1 some failed or are unreadable (everything is still written); 2 a bad
argument, a path without runs, or compare= naming a key that is not swept.

examples:
  {PROG} outputs/multirun/2026-01-01_12-00-00
  {PROG} outputs/multirun/a outputs/multirun/b split=val compare=objective latex=true out=report
  {PROG} outputs/multirun/tuned exclude='*/search/*' results=docs/results reproduction=true
"""
KEYS = {
    "split": Key("choice", "test", SPLITS),
    "metric": Key("choice", "mean_rel_dev", tuple(METRICS)),
    "out": Key(),
    "compare": Key(),
    "exclude": Key("list", repeats=True),
    "notes": Key(),
    "results": Key(),
    "merge": Key("list", repeats=True),
    "latex": Key("bool", False),
    "reproduction": Key("bool", False),
    "run_figures": Key("bool", False),
}


def parse_args(argv) -> Namespace:
    """PATHs and key=value options -> the report's settings, each checked (UsageError)."""
    values, paths = parse(list(argv), KEYS, positional=True)
    args = Namespace(**values, paths=[Path(p) for p in paths])
    args.exclude = [pattern for group in args.exclude for pattern in group]
    for group in args.merge:
        if len(group) < 2:
            raise UsageError("merge", ",".join(group), "two or more sweeps: merge=DIR,DIR")
    args.merge = [[Path(p) for p in group] for group in args.merge]
    for key in ("out", "notes", "results"):
        setattr(args, key, None if getattr(args, key) is None else Path(getattr(args, key)))
    if not args.paths:
        raise UsageError(
            "PATH", missing=True, allowed=f"at least one run or sweep directory: {PROG} PATH... (see --help)"
        )
    if args.merge and args.results is None:
        raise UsageError("merge", allowed="with results=DIR (it adds a section to the results)")
    return args


def _error(message: str) -> int:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    """The command. SIGTERM or SIGINT ends it with one line and 128 + the signal's number; a file being written
    then is left as it was, its temporary file removed (the default SIGTERM left it in figures/)."""
    tolerant_streams()
    caught = [s for s in (signal.SIGTERM, signal.SIGINT) if signal.getsignal(s) is not signal.SIG_IGN]
    received: list[int] = []

    def interrupt(signum, frame):
        # raised into the report's own code (it has no safe points), so write_atomic's cleanup runs on the way
        received.append(signum)
        raise Interrupted(signum)

    def unraisable(hook, default=sys.unraisablehook):
        # a finaliser the signal landed in swallows the exception: the report then goes on, and still ends
        # with the signal's status, without Python's "Exception ignored" traceback
        if not isinstance(hook.exc_value, Interrupted):
            default(hook)

    previous = {s: signal.signal(s, interrupt) for s in caught}
    previous_hook, sys.unraisablehook = sys.unraisablehook, unraisable
    try:
        status = _main(argv)
    except Interrupted:
        status = None
    finally:
        sys.unraisablehook = previous_hook
        for s, handler in previous.items():
            signal.signal(s, handler)
    if received:
        name = signal.Signals(received[0]).name
        print(
            f"error: {PROG} interrupted by {name}; each file it wrote is whole, the others as they were",
            file=sys.stderr,
        )
        return 128 + received[0]
    return status


def _main(argv) -> int:
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
            return _error(str(UsageError("PATH", Shown(str(path)), "a run or sweep directory that exists")))
        if not find_runs(path):
            return _error(str(UsageError("PATH", Shown(str(path)), f"a directory with runs ({RECORD}) at or below it")))
    if args.notes is not None and not args.notes.is_file():
        return _error(str(UsageError("notes", Shown(str(args.notes)), "a markdown file that exists")))
    refused = _inside_a_run(args)
    if refused:
        return _error(refused)
    from hybrid_sysid.cli.report_files import write_report  # deferred

    try:
        return write_report(args, shlex.join([PROG, *argv]))
    except ValueError as exc:  # e.g. compare= naming a key that is not swept
        return _error(str(exc))
    except OSError as exc:  # e.g. out= on a read-only file system: the runs themselves are untouched
        return _error(f"cannot write the report: {type(exc).__name__}: {exc}")


def _inside_a_run(args) -> str | None:
    """results= never lies inside a run or sweep directory, whose files are their record (a results page there
    once replaced a run's metrics.json); out= neither, but for a PATH itself, where the summary goes by default."""
    own = {p.resolve() for p in args.paths}
    for key in ("results", "out"):
        value = getattr(args, key)
        if value is None or (key == "out" and Path(value).resolve() in own):
            continue
        try:
            check_outside_runs(key, value, error=UsageError)
        except UsageError as exc:
            return str(exc)
    return None
