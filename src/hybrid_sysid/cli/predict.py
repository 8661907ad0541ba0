"""``hybrid-sysid-predict``: estimate p1, p2 and the seat mass m3 of recordings with a trained run.

    hybrid-sysid-predict run=DIR input=FILE [output=CSV] [windows=K] [resample=true] [dt=SECONDS]

The command parses its key=value arguments, reads the file and prints; the estimates come from
``hybrid_sysid.inference.estimator``, the code the Python API runs. Bad input prints one line on stderr naming the
problem and exits with status 2. File formats and output columns: docs/predict.md.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pandas as pd

from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.inference.estimator import InputError, load_estimator
from hybrid_sysid.inference.readers import read_input

USAGE = "usage: hybrid-sysid-predict run=DIR input=FILE [output=CSV] [windows=K] [resample=true|false] [dt=SECONDS]"
KEYS = ("run", "input", "output", "windows", "resample", "dt")


def parse_args(argv: list[str]) -> dict:
    """key=value arguments -> {run, input, output, windows, resample, dt}, each checked."""
    args: dict = {}
    for arg in argv:
        key, sep, value = arg.partition("=")
        if not sep:
            raise InputError(f"argument {arg!r} is not key=value; allowed keys: {', '.join(KEYS)}")
        if key not in KEYS:
            raise InputError(f"unknown key {key!r} in {arg!r}; allowed keys: {', '.join(KEYS)}")
        if key in args:
            raise InputError(f"{key} is given twice ({key}={args[key]} and {arg}); give it once")
        args[key] = value
    for key in ("run", "input"):
        if not args.get(key):
            raise InputError(f"{key}= is missing; {USAGE}")
    windows = args.get("windows", "8")
    try:
        args["windows"] = int(windows)
    except ValueError:
        args["windows"] = 0
    if args["windows"] < 1:
        raise InputError(f"windows = {windows!r} is not allowed: an integer >= 1")
    resample = args.get("resample", "false").lower()
    if resample not in ("true", "false"):
        raise InputError(f"resample = {args['resample']!r} is not allowed: true or false")
    args["resample"] = resample == "true"
    if "dt" in args:
        try:
            dt = float(args["dt"])
        except ValueError:
            dt = math.nan
        if not (math.isfinite(dt) and dt > 0):
            raise InputError(f"dt = {args['dt']!r} is not allowed: a sampling interval > 0 in seconds")
        args["dt"] = dt
    return args


def run(args: dict) -> pd.DataFrame:
    """Read, estimate, print the table and write output= when given."""
    output = Path(args["output"]) if args.get("output") else None
    if output is not None and not output.parent.is_dir():
        raise InputError(f"output = {output}: its directory {output.parent} does not exist")
    recordings = read_input(Path(args["input"]), args.get("dt"))
    estimator = load_estimator(args["run"])
    try:
        table = estimator.predict(
            recordings.seat,
            recordings.body,
            recordings.dt,
            windows=args["windows"],
            resample=args["resample"],
            names=recordings.names,
        )
    except InputError as exc:
        raise InputError(f"input = {args['input']}: {exc}") from None
    print(table.to_string(index=False))
    if output is not None:
        try:
            write_atomic(output, lambda tmp: table.to_csv(tmp, index=False))
        except OSError as exc:
            raise InputError(f"output = {output} cannot be written ({exc})") from None
    return table


def main(argv: list[str] | None = None) -> None:
    """Console script; exit status 2 with one line on stderr for bad input."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in ("-h", "--help"):
        print(__doc__)
        return
    try:
        run(parse_args(argv))
    except InputError as exc:
        print(f"hybrid-sysid-predict: error: {' '.join(str(exc).split())}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
