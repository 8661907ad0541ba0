"""``hybrid-sysid-predict``: estimate p1, p2 and the seat mass m3 of recordings with a trained run.

    hybrid-sysid-predict run=DIR input=FILE [output=CSV] [overwrite=true] [windows=K] [resample=true] [dt=SECONDS]

The command parses its key=value arguments, reads the file and prints; the estimates come from
``hybrid_sysid.inference.estimator``, the code the Python API runs. Bad input prints one line on stderr naming the
problem and exits with status 2 (so does running out of memory); Ctrl-C prints one line and exits with status
130. output= never replaces the input, a file inside a run or sweep directory, or (without overwrite=true) any
existing file. Estimates not to trust are marked in the column flag, with one warning line per kind on stderr.
File formats, output columns and flags: docs/predict.md.
"""

from __future__ import annotations

import os
import sys
import tempfile
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import hybrid_sysid
from hybrid_sysid.cli.arguments import Key, UsageError, parse
from hybrid_sysid.core.checks import ConfigError, Shown
from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.inference.inputs import EstimateWarning, InputError, check_windows
from hybrid_sysid.launch.console import tolerant_streams
from hybrid_sysid.runs import layout

if TYPE_CHECKING:
    import pandas as pd

USAGE = (
    "usage: hybrid-sysid-predict run=DIR input=FILE [output=CSV] [overwrite=true|false] [windows=K] "
    "[resample=true|false] [dt=SECONDS]"
)
KEYS = {
    "run": Key(),
    "input": Key(),
    "output": Key(),
    "overwrite": Key("bool", False),
    "windows": Key("int", 8, check=check_windows),
    "resample": Key("bool", False),
    "dt": Key("dt", allowed="a sampling interval > 0 in seconds"),
}


def parse_args(argv: list[str]) -> dict:
    """key=value arguments -> {run, input, output, overwrite, windows, resample, dt}, each checked (the shared
    parser, hybrid_sysid.cli.arguments)."""
    args, _ = parse(argv, KEYS)
    for key in ("run", "input"):
        if not args.get(key):
            raise UsageError(key, missing=True, allowed=USAGE)
    return args


def check_output(args: dict) -> Path | None:
    """output= as a Path, after checking it replaces nothing it must not: not the input (also through a link or
    another spelling of its path), no file inside a run or sweep directory (run= or any directory above it that
    holds .hydra/, a record or a sweep's multirun.yaml), and no existing file unless overwrite=true."""
    if not args.get("output"):
        return None
    output = Path(args["output"])

    def refuse(allowed: str):
        raise UsageError("output", Shown(args["output"]), allowed)

    if not output.parent.is_dir():
        refuse(f"a file in a directory that exists ({output.parent} does not)")
    if output.is_dir():
        refuse("a file name for the CSV table, not a directory")
    target, source = output.resolve(), Path(args["input"])
    if target == source.resolve() or (output.exists() and source.exists() and os.path.samefile(output, source)):
        refuse(f"it is the input file (input = {args['input']}); another file, an output never replaces its input")
    if target.is_relative_to(Path(args["run"]).resolve()):
        refuse(f"it lies inside the run directory run = {args['run']}; {layout.OUTSIDE_RUNS}")
    layout.check_outside_runs("output", args["output"], error=UsageError)  # a sweep's directory too
    if (output.exists() or output.is_symlink()) and not args.get("overwrite"):
        refuse("it exists; a new file, or overwrite=true to replace it")
    if output.is_symlink() or (output.exists() and not output.is_file()):
        # the rename would put a file in the link's or the FIFO's place: /dev/stdout, run as root, is such a link
        refuse("a regular file or a new name to write the table to; it is a symbolic link, FIFO or device")
    return output


def write_new(path: Path, write) -> None:
    """``write(tmp)`` fills a temporary file beside ``path``, which then becomes ``path`` by a hard link, which
    fails if ``path`` exists: a file that appeared since check_output is never replaced, and no reader sees half
    a file. Where hard links are not supported, a rename after a last check."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)  # the mode a plain open() gives, as write_atomic does
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        write(Path(tmp))
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise
        except OSError:  # a filesystem without hard links
            if path.exists() or path.is_symlink():
                raise FileExistsError(path) from None
            os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)


# pandas, torch and Lightning take seconds to import: inside main(), where Ctrl-C meanwhile is its one line and
# exit status 130, not a traceback from the console script's import of this module


def read_input(path: Path, dt: float | None):
    from hybrid_sysid.data.readers import read_input as read  # deferred

    return read(path, dt)


def load_estimator(run_dir: str):
    return hybrid_sysid.load_estimator(run_dir)  # the package's own deferred import


def run(args: dict) -> pd.DataFrame:
    """Read, estimate, print the table, write output= when given, then a warning line per kind of flag on stderr."""
    output = check_output(args)
    recordings = read_input(Path(args["input"]), args.get("dt"))
    estimator = load_estimator(args["run"])
    try:
        with warnings.catch_warnings():  # the same lines are printed below, once each, in the command's form
            warnings.simplefilter("ignore", EstimateWarning)
            table = estimator.predict(
                recordings.seat,
                recordings.body,
                recordings.dt,
                windows=args["windows"],
                resample=args["resample"],
                names=recordings.names,
            )
    except InputError as exc:  # the recordings' own problem, in the file named by input=
        raise InputError(f"input = {args['input']}: {exc.key}", exc.value, exc.allowed, exc.missing) from None
    print(table.to_string(index=False))
    if output is not None:
        write = write_atomic if args.get("overwrite") else write_new
        try:
            write(output, lambda tmp: table.to_csv(tmp, index=False))
        except FileExistsError:
            raise UsageError(
                "output",
                Shown(args["output"]),
                "it appeared while the recordings were estimated and is left as it is; a new file, or overwrite=true "
                "to replace it",
            ) from None
        except OSError as exc:
            raise UsageError("output", Shown(str(output)), f"a file that can be written ({exc})") from None
    for line in table.attrs.get("warnings", []):  # last: a refusal or Ctrl-C before this stays one line
        print(f"hybrid-sysid-predict: warning: {line}", file=sys.stderr)
    return table


HELP = """hybrid-sysid-predict: estimate p1 = C3/m3, p2 = K3/m3 and the seat mass m3 of your own recordings (seat and
body accelerations in m/s^2, CSV or .npz) with a trained run's network; prints a table, one row per recording.

{usage}

  run=DIR             a run directory written by hybrid-sysid (its .hydra/config.yaml and checkpoints/)
  input=FILE          the recordings: a CSV (columns seat_acc, body_acc, and time unless dt= is given) or .npz
  output=CSV          also write the table to this new file (never the input, nor inside a run or sweep directory)
  overwrite=true      let output= replace an existing file
  windows=K           average the estimates of K windows per recording (default 8)
  resample=true       resample recordings sampled at another rate than the run's data.dt
  dt=SECONDS          the sampling interval, when the file does not give it

Exit status: 0 done; 2 bad input or out of memory (one line on stderr); 130 Ctrl-C. File formats, columns and flags:
docs/predict.md.

example:
  hybrid-sysid-predict run=outputs/runs/2026-01-01_12-00-00 input=drive.csv output=estimates.csv
"""


def main(argv: list[str] | None = None) -> None:
    """Console script; exit status 2 with one line on stderr for bad input, 130 for Ctrl-C (128 + SIGINT)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    tolerant_streams()  # an ASCII locale cannot encode a recording's or a path's name
    if any(a in ("-h", "--help") for a in argv):
        print(HELP.format(usage=USAGE), end="")
        return
    try:
        run(parse_args(argv))
    except ConfigError as exc:
        print(f"hybrid-sysid-predict: error: {' '.join(str(exc).split())}", file=sys.stderr)
        sys.exit(2)
    except MemoryError:  # beyond what the windows' check foresees: the run, the file, the channel reference
        print(
            "hybrid-sysid-predict: error: out of memory: the recordings need more than this process may use (free "
            "memory, its address-space limit, ulimit -v, or its cgroup's); fewer recordings per input file, or a "
            "smaller windows=",
            file=sys.stderr,
        )
        sys.exit(2)
    except KeyboardInterrupt:
        print("hybrid-sysid-predict: interrupted (Ctrl-C)", file=sys.stderr)
        sys.exit(130)


if __name__ == "__main__":
    main()
