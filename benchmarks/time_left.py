"""A sweep's time-left estimates against the truth, replayed from its progress file (hybrid_sysid.launch.progress).

At each job's end, and at each step line a worker printed, the estimate from the events written until then, and
the time that really remained: the last job's end minus that moment. "at least" marks a lower bound (a kind of job
with no time yet).

    python benchmarks/time_left.py <sweep directory> [...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hybrid_sysid.launch.time_left import estimate


def clock(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}:{s:02d}"


def replay(sweep_dir: Path, guess: bool = False) -> list[tuple[str, float, float, float, int]]:
    """(what, sweep clock, estimate, truth, jobs not timed) at each end but the last and each step line; with
    ``guess``, the estimate the job line gives beside a lower bound (kinds at their times under another fault)."""
    header, *events = map(json.loads, (sweep_dir / ".progress").read_text().splitlines())
    last = max(e["t"] for e in events if "end" in e)
    out = []
    for n, e in enumerate(events):
        if e["t"] >= last or not ("end" in e or "said" in e):
            continue
        said = estimate(header, events[: n + 1], e["t"], guess=guess)
        if said is not None:
            what = f"end #{e['end']}" if "end" in e else f"steps #{e['said']}"
            out.append((what, e["t"] - header["start"], said[0], last - e["t"], said[1]))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sweeps", nargs="+", type=Path)
    parser.add_argument("--guess", action="store_true", help="the estimate said beside a lower bound")
    args = parser.parse_args()
    for sweep_dir in args.sweeps:
        print(sweep_dir)
        for what, at, seconds, truth, untimed in replay(sweep_dir, args.guess):
            said = f"at least {clock(seconds)}" if untimed else f"about {clock(seconds)}"
            error = "" if untimed else f" ({100 * (seconds - truth) / truth:+.0f}%)"
            print(f"  {clock(at)} {what:10s} {said:>16s} left, truth {clock(truth)}{error}")


if __name__ == "__main__":
    main()
