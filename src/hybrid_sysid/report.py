"""hybrid-sysid-report PATH...: rebuild the sweep tables and figures from run or sweep directories.

Exit code: 0 if every run completed, 1 if any failed or is unreadable (everything is still written),
2 if a path does not exist or holds no runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hybrid_sysid.evaluation.records import RECORD
from hybrid_sysid.evaluation.summary import METRICS, find_runs, to_markdown, write_summary

PROG = "hybrid-sysid-report"


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog=PROG, description="Rebuild the sweep tables and figures from run or sweep "
                                "directories (merged). Exit 0: all runs completed; 1: some failed; 2: bad path.")
    p.add_argument("paths", nargs="+", type=Path, metavar="PATH", help="run or sweep directories (merged)")
    p.add_argument("--split", default="test", help="split of the table and figures (default: test)")
    p.add_argument("--metric", default="mean_rel_dev", choices=list(METRICS), help="default: mean_rel_dev")
    p.add_argument("--out", type=Path, default=None,
                   help="output directory (default: the PATH if one is given, else ./report)")
    p.add_argument("--compare", default=None, metavar="KEY",
                   help="the swept key whose rows the marks compare (default: objective when swept)")
    p.add_argument("--latex", action="store_true", help="also write summary.tex (a booktabs table)")
    return p.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    for path in args.paths:  # each path must contribute, so a typo is not silently merged away
        if not path.exists():
            print(f"{PROG}: error: path does not exist: {path}", file=sys.stderr)
            return 2
        if not find_runs([path]):
            print(f"{PROG}: error: no runs ({RECORD}) under {path}", file=sys.stderr)
            return 2
    out = args.out or (args.paths[0] if len(args.paths) == 1 else Path("report"))
    try:
        df, table = write_summary(out, paths=args.paths, split=args.split, metric=args.metric, latex=args.latex,
                                  compare=args.compare)
    except ValueError as exc:  # e.g. --compare naming a key that is not swept
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    print(to_markdown(table, compare=args.compare), end="")
    runs = df.drop_duplicates("run")
    bad = int((runs.status != "completed").sum())
    tex = ", summary.tex" if args.latex else ""
    print(f"{len(runs)} runs, {bad} failed or unreadable; wrote {out}/summary.csv, summary.md{tex}, figures/",
          file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
