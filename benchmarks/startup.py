"""What starting a command costs: the CPU time (user + system, the process and its children) of ``--help`` and of
each refusal that comes before any work, and which heavy modules the command imported on the way.

    python benchmarks/startup.py [--rounds 3] [--importtime] [--against SRC]

Each command runs ``--rounds`` times in a fresh process, in an empty temporary directory (a refusal leaves nothing
behind, and nothing here is read from the repository's outputs). CPU time rather than wall time: the machines these
run on are shared, and a process's CPU time moves much less with the load beside it. Reported per command: the
exit status (0 for --help, 2 for a refusal), the CPU times of the rounds and their median. The goal (issue "Fast on
the CPU people have"): every one under 1 s.

``--against SRC`` times the same commands with another source tree's package as well (``git archive <commit> src |
tar -x -C DIR``, then ``--against DIR/src``), the two alternating run by run, so a change of the machine's load
touches both alike.

``--importtime`` adds, per command, the heavy modules (Lightning, torch, scipy.signal, numba, matplotlib, pandas)
that one more run imported, read from ``python -X importtime``'s stderr with their cumulative import time.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile

from machine import cpu_name, load_average

HEAVY = ("lightning", "torch", "scipy.signal", "numba", "matplotlib", "pandas")
# the commands of the issue: --help and the refusals before any work, each (name, console script, arguments); the
# console scripts are the installed ones beside this interpreter, as a user starts them
COMMANDS = [
    ("hybrid-sysid --help", "hybrid-sysid", ["--help"]),
    ("hybrid-sysid trainer.max_steps=-1", "hybrid-sysid", ["trainer.max_steps=-1"]),
    ("hybrid-sysid objective=nonexistent", "hybrid-sysid", ["objective=nonexistent"]),
    ("hybrid-sysid model.net.depth=3 (no such key)", "hybrid-sysid", ["model.net.depth=3"]),
    ("hybrid-sysid trainer.max_steps=abc", "hybrid-sysid", ["trainer.max_steps=abc"]),
    ("hybrid-sysid model.net.blend=3", "hybrid-sysid", ["estimator=anchored_cross_segment", "model.net.blend=3"]),
    ("hybrid-sysid objective.target=xx", "hybrid-sysid", ["objective=cross_segment", "objective.target=xx"]),
    ("hybrid-sysid data.window=8", "hybrid-sysid", ["data.window=8"]),
    ("hybrid-sysid-predict (missing input)", "hybrid-sysid-predict", ["run=no_run", "input=missing.csv"]),
    ("hybrid-sysid-report (missing directory)", "hybrid-sysid-report", ["missing_sweep"]),
    ("hybrid-sysid-eval (missing run)", "hybrid-sysid-eval", ["run=no_run"]),
]


def cpu_seconds(argv: list[str], cwd: str, src: str | None = None) -> tuple[float, int]:
    """User + system CPU seconds of one run of ``argv`` (and anything it started), and its exit status; with
    ``src``, the package imported from that source tree."""
    env = dict(os.environ, PYTHONPATH=src) if src else None
    proc = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return usage.ru_utime + usage.ru_stime, proc.returncode


def heavy_imports(argv: list[str], cwd: str) -> dict[str, float]:
    """The heavy top-level modules one run imported, each with its cumulative import time in seconds."""
    err = subprocess.run(
        [sys.executable, "-X", "importtime", *argv], cwd=cwd, capture_output=True, text=True
    ).stderr  # the console script is a Python file: run by this interpreter with -X importtime
    found = {}
    for line in err.splitlines():
        m = re.match(r"import time:\s+\d+ \|\s+(\d+) \|( *)(\S+)$", line)
        if m and m.group(3) in HEAVY:
            found[m.group(3)] = int(m.group(1)) / 1e6
    return found


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--importtime", action="store_true")
    ap.add_argument("--against", metavar="SRC", help="another source tree's src/ folder, timed alternately")
    args = ap.parse_args()
    print(f"CPU: {cpu_name()}, load average {load_average()}, python {sys.version.split()[0]}")
    with tempfile.TemporaryDirectory() as cwd:
        for name, script, rest in COMMANDS:
            argv = [os.path.join(os.path.dirname(sys.executable), script), *rest]
            runs, other = [], []
            for _ in range(args.rounds):
                runs.append(cpu_seconds(argv, cwd))
                if args.against:
                    other.append(cpu_seconds(argv, cwd, args.against))
            for label, timed in (("", runs), (f"  ({args.against})", other)):
                if timed:
                    times = ", ".join(f"{t:.2f}" for t, _ in timed)
                    codes = sorted({c for _, c in timed})
                    median = statistics.median(t for t, _ in timed)
                    print(f"{name + label:42s} exit {codes}  CPU s: {times}  median {median:.2f}")
            if args.importtime:
                heavy = heavy_imports(argv, cwd)
                shown = ", ".join(f"{k} {v:.2f} s" for k, v in heavy.items()) or "none"
                print(f"{'':42s} heavy imports: {shown}")
            leftover = os.listdir(cwd)
            if leftover:
                print(f"{'':42s} left behind: {leftover}")


if __name__ == "__main__":
    main()
