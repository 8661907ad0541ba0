"""Finding run directories and reading their records into one long-form table.

A run is a directory holding a record (metrics.json). Hydra's files beside it (.hydra/overrides.yaml,
config.yaml, hydra.yaml) give a run's configuration when its record cannot be read, and the value of a key the run
did not override. Override values stay the strings Hydra recorded, so "0.002" and "2e-3" stay distinct rows. A
results row's "windows" (K, test-time averaging over K windows per recording) is 1 when absent.
"""

from __future__ import annotations

import math
import os
from fnmatch import fnmatch
from pathlib import Path

import pandas as pd

from hybrid_sysid.core.checks import bad
from hybrid_sysid.core.files import readable
from hybrid_sysid.core.overrides import parse_overrides
from hybrid_sysid.model.metrics import PARAMETERS, relative_deviation
from hybrid_sysid.runs.layout import PREDICTIONS, RECORD
from hybrid_sysid.runs.reading import find_runs as runs_below
from hybrid_sysid.runs.rundir import DamagedFile, RunDir

HEAD = ["run", "status", "error", "seed"]
TAIL = [
    "split",
    "noise_std",
    "windows",
    "parameter",
    "mean_rel_dev",
    "std_rel_dev",
    "n",
    "bound",
    "bound_output",
    "efficiency",
    "steps",
    "train_seconds",
    "threads",
    "git_commit",
    "git_dirty",
    "cpu",
    "reference",
]
RESULT = ["split", "noise_std", "parameter", "mean_rel_dev", "std_rel_dev", "n"]  # required in a results row
BOUND = ["bound", "bound_output", "efficiency"]  # a test row's Cramér-Rao bound (absent from older records)


def run_config(run_dir) -> dict:
    """The run's composed config as Hydra saved it (interpolations unresolved), {} if absent."""
    return RunDir(run_dir).saved_values()


def run_choices(run_dir) -> dict:
    """The run's config-group choices (objective, model, data, ...), {} if absent."""
    return RunDir(run_dir).choices()


def config_value(cfg, dotted: str):
    """cfg["a"]["b"] for dotted "a.b"; None where a level is missing."""
    for part in dotted.split("."):
        if not isinstance(cfg, dict) or part not in cfg:
            return None
        cfg = cfg[part]
    return cfg


def natural_key(values) -> list[tuple]:
    """A sort key for a value or a tuple of values: numbers in numeric order ("9" before "10"), then text."""
    out = []
    for v in values if isinstance(values, tuple) else (values,):
        try:
            f = float(v)
            out.append((0, f, "") if not math.isnan(f) else (1, 0.0, str(v)))
        except (TypeError, ValueError):
            out.append((1, 0.0, str(v)))
    return out


def _as_paths(paths) -> list[Path]:
    return [Path(paths)] if isinstance(paths, (str, os.PathLike)) else [Path(p) for p in paths]


def find_runs(paths) -> list[Path]:
    """Every directory holding a record at or below each path (a run, a sweep, or a parent of sweeps), in
    natural order, so Hydra's job 10 follows job 9."""
    found = {run for path in _as_paths(paths) for run in runs_below(path)}
    return sorted(found, key=lambda p: natural_key(p.parts))


def _overrides(parsed) -> dict[str, str]:
    """A run's parsed overrides as columns: "+key=v", "++key=v" and "~key" name the key of "key=v" (a deletion
    reads as empty); a path outside ASCII as its table and figures show it."""
    return {readable(o.key): "" if o.deletes or o.value is None else readable(o.value) for o in parsed}


BOUND_MAX = 1e6  # a relative deviation of 1e8 %: far above any window's bound (116% at noise 0.1), and x 100 finite


def _bound(value):
    """A Cramér-Rao column of a results row: a number in [0, BOUND_MAX], else unknown (None). A record edited to
    a negative, infinite, huge or text bound made the table's bound row read -12.50% or inf."""
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and 0 <= value <= BOUND_MAX
    return value if ok else None


def _text(value) -> str:
    """A record's text field as one short line: a received record may hold anything there."""
    return " ".join(str(value).split())[:80]


def _rows_of(run_dir: Path, name: str) -> list[dict]:
    run = RunDir(run_dir)
    try:
        rec = run.record(name)
        base = {
            "run": name,
            "status": str(rec["status"]),
            "error": rec.get("error"),
            "seed": rec.get("seed"),
            "steps": rec.get("steps"),
            "train_seconds": rec.get("train_seconds"),
            "threads": rec.get("threads"),
            # the code and the processor that made the numbers (absent from records made before they were kept)
            "git_commit": rec.get("git_commit"),
            "git_dirty": rec.get("git_dirty"),
            "cpu": rec.get("cpu"),
            # what the deviations are measured from: "labels", or a fit where a user's recordings have none
            "reference": _text(rec.get("reference", "labels")),
        }
        overrides = _overrides(parse_overrides(rec.get("overrides")))
        results = [
            {**{k: r[k] for k in RESULT}, "windows": r.get("windows", 1), **{k: _bound(r.get(k)) for k in BOUND}}
            for r in rec.get("results") or []
        ]
        for r in results:  # a deviation that is no number >= 0 (text, a negative) is no measurement
            for key in ("mean_rel_dev", "std_rel_dev"):
                if isinstance(r[key], bool) or not isinstance(r[key], (int, float)) or r[key] < 0:
                    raise TypeError(f"{key} = {r[key]!r} in a results row: a relative deviation is a number >= 0")
    except (DamagedFile, TypeError, KeyError, AttributeError) as exc:
        # Hydra writes .hydra/overrides.yaml before a job starts, so a job whose record is corrupt still has a
        # known configuration and lands in the right row of the table
        overrides = _overrides(run.parsed_overrides())
        seed = overrides.get("seed", "")
        base = {
            "run": name,
            "status": "unreadable",
            "error": exc.why if isinstance(exc, DamagedFile) else f"{type(exc).__name__}: {exc}",
            "seed": int(seed) if seed.lstrip("-").isdigit() else None,
        }
        results = []
    overrides.pop("seed", None)  # the record's own seed column is authoritative
    # a key named like a fixed column (unlikely) is prefixed rather than allowed to overwrite it
    overrides = {(f"override:{k}" if k in HEAD + TAIL else k): v for k, v in overrides.items()}
    return [{**base, **overrides, **r} for r in results or [{}]]  # no results: one row, NaN metrics


def load_runs(paths, exclude=()) -> tuple[Path, pd.DataFrame]:
    """The runs at or below paths in long form (see collect), and the directory their names are relative to:
    the inputs' common parent, so runs of two merged sweeps ("a/0", "b/0") never share a name, and a single run
    is named by its own name. Runs whose name matches a glob pattern of ``exclude`` (e.g. "*/search/*") are left
    out. Raises ValueError when the paths hold no run."""
    paths = _as_paths(paths)
    runs = find_runs(paths)
    if not runs:
        bad("paths", [str(p) for p in paths], f"directories with runs ({RECORD}) at or below them")
    root = Path(os.path.commonpath([p.resolve() for p in paths]))
    root = root.parent if root in runs else root
    names = {run.relative_to(root).as_posix(): run for run in runs}
    names = {name: run for name, run in names.items() if not any(fnmatch(name, p) for p in exclude)}
    if not names:
        bad("exclude", list(exclude), f"patterns that leave some runs under {[str(p) for p in paths]}")
    df = pd.DataFrame([row for name, run in names.items() for row in _rows_of(run, name)])
    keys = [c for c in df.columns if c not in HEAD + TAIL]  # first-seen order across runs
    df = df.reindex(columns=HEAD + keys + TAIL)
    df[keys] = df[keys].fillna("").astype(str)
    # a run without a key ran with that key's default: read it from the run's saved choices or config, so
    # sweeps merged with other sweeps land in the right rows ("" only when the run has no .hydra/)
    for key in keys:
        blank = df[key] == ""
        for name in df.loc[blank, "run"].unique():
            choices = run_choices(names[name])
            value = choices[key] if key in choices else config_value(run_config(names[name]), key)
            df.loc[blank & (df.run == name), key] = "" if value is None else str(value)
    for col in ("seed", "windows", "n", "steps", "threads"):
        df[col] = pd.to_numeric(df[col], errors="coerce").round().astype("Int64")  # NaN-safe, writes "1" not "1.0"
    for col in ("noise_std", "mean_rel_dev", "std_rel_dev", "train_seconds", *BOUND):
        df[col] = pd.to_numeric(df[col], errors="coerce").astype(float)
    return root, df


def collect(paths) -> pd.DataFrame:
    """Long form: one row per job x split x noise_std x windows x parameter; a failed or unreadable job is one
    row with NaN metrics. Columns: run, status, error, seed, one per override key (strings, "" if unset), split,
    noise_std, windows, parameter, mean_rel_dev, std_rel_dev, n, bound, bound_output and efficiency (a test row's
    Cramér-Rao bound and how near the estimator comes to it: model.metrics.bound_fields), steps, train_seconds,
    threads (torch's thread
    count), git_commit and git_dirty (the checkout the run's code came from, and whether its tracked files differed
    from that commit), cpu (the processor's model name); the last four are empty for records written before they
    were recorded."""
    return load_runs(paths)[1]


def row_keys(df: pd.DataFrame) -> list[str]:
    """The swept keys other than seed: those whose values differ between runs. Runs whose configuration is
    unknown (unreadable, no .hydra) are left out of this choice so they cannot make every key look swept."""
    runs = df.drop_duplicates("run")
    known = runs[runs.status != "unreadable"]
    runs = known if len(known) else runs
    return [k for k in df.columns if k not in HEAD + TAIL and runs[k].nunique() > 1]


def load_predictions(root: Path, df: pd.DataFrame, split: str = "test") -> pd.DataFrame:
    """Per recording and evaluation, the relative deviation |p - p_pred| / p (eq. 24) of each completed run's
    predictions.csv on ``split``, in long form: run, noise_std, windows, recording, parameter, rel_dev. Runs
    without the file (or with a damaged one) are left out."""
    frames = []
    for run in df[df.status == "completed"].run.unique():
        try:
            p = RunDir(Path(root) / run).read_table(PREDICTIONS)
            p = p[p.split == split]
            names = list(PARAMETERS)
            devs = relative_deviation(
                p[[f"{n}_pred" for n in names]].to_numpy(), p[[f"{n}_true" for n in names]].to_numpy()
            )
            for i, name in enumerate(names):
                dev = devs[:, i]
                frames.append(
                    pd.DataFrame(
                        {
                            "run": run,
                            "noise_std": p.noise_std.astype(float),
                            "windows": p.windows.astype(int),
                            "recording": p.recording,
                            "parameter": name,
                            "rel_dev": dev,
                        }
                    )
                )
        except (OSError, ValueError, KeyError, AttributeError):
            continue
    return (
        pd.concat(frames, ignore_index=True)
        if frames
        else pd.DataFrame(columns=["run", "noise_std", "windows", "recording", "parameter", "rel_dev"])
    )
