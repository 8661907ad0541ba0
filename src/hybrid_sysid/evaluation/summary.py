"""Sweep summary built from run records on disk alone: long-form table, comparison table, markdown, figures.

The spread over seeds is the sample standard deviation (ddof=1) everywhere; with a single seed it is NaN and the
markdown shows no "±". Override values stay the strings Hydra recorded, so "0.002" and "2e-3" stay distinct rows.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Iterable

import pandas as pd

from hybrid_sysid.evaluation import sweep_plots
from hybrid_sysid.evaluation.records import RECORD

METRICS = {"mean_rel_dev": "mean relative deviation", "std_rel_dev": "std of relative deviation"}
HEAD = ["run", "status", "error", "seed"]
TAIL = ["split", "noise_std", "parameter", "mean_rel_dev", "std_rel_dev", "n", "steps", "train_seconds"]
NO_KEYS = "all"  # the single row label when no override varies across runs


def _as_paths(paths: str | os.PathLike | Iterable) -> list[Path]:
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    return [Path(p) for p in paths]


def find_runs(paths) -> list[Path]:
    """Every directory holding a metrics.json at or below each path (a run, a sweep, or a parent of sweeps)."""
    found = set()
    for path in _as_paths(paths):
        if (path / RECORD).is_file():
            found.add(path.resolve())
        found.update(p.parent.resolve() for p in path.rglob(RECORD) if p.is_file())
    # Hydra numbers jobs 0, 1, ..., 10: sort those numerically so job 10 follows job 9
    return sorted(found, key=lambda p: [(0, int(s), "") if s.isdigit() else (1, 0, s) for s in p.parts])


def _resolve(paths) -> tuple[Path, list[Path]]:
    """The runs, and the directory their names are relative to: the inputs' common parent, so runs of two
    merged sweeps ("a/0", "b/0") never share a name, and a single run dir is named by its own name."""
    paths = _as_paths(paths)
    runs = find_runs(paths)
    if not runs:
        return Path.cwd(), runs
    root = Path(os.path.commonpath([p.resolve() for p in paths]))
    return (root.parent if root in runs else root), runs


def _parse_overrides(items) -> dict[str, str]:
    out = {}
    for item in items:
        key, _, value = str(item).partition("=")
        out[key.lstrip("+")] = value  # "+key=v" / "++key=v" set the same key as "key=v"
    return out


def _hydra_overrides(run_dir: Path) -> list[str]:
    """Hydra writes .hydra/overrides.yaml before a job starts, so a job whose record is corrupt still has a
    known configuration and lands in the right row of the table."""
    try:
        import yaml  # a dependency of omegaconf

        items = yaml.safe_load((run_dir / ".hydra" / "overrides.yaml").read_text())
        return [str(i) for i in items] if isinstance(items, list) else []
    except Exception:  # noqa: BLE001 - best effort; the job is reported as unreadable either way
        return []


def _rows_of(run_dir: Path, name: str) -> list[dict]:
    try:
        rec = json.loads((run_dir / RECORD).read_text())
        base = {"run": name, "status": str(rec["status"]), "error": rec.get("error"), "seed": rec.get("seed"),
                "steps": rec.get("steps"), "train_seconds": rec.get("train_seconds")}
        overrides = _parse_overrides(rec.get("overrides") or [])
        results = [{k: r[k] for k in TAIL[:6]} for r in rec.get("results") or []]
    except (OSError, ValueError, TypeError, KeyError, AttributeError) as exc:
        overrides = _parse_overrides(_hydra_overrides(run_dir))
        seed = overrides.get("seed", "")
        base = {"run": name, "status": "unreadable", "error": f"{type(exc).__name__}: {exc}",
                "seed": int(seed) if seed.lstrip("-").isdigit() else None}
        results = []
    overrides.pop("seed", None)  # the record's own seed column is authoritative
    # a key named like a fixed column (unlikely) is prefixed rather than allowed to overwrite it
    overrides = {(f"override:{k}" if k in HEAD + TAIL else k): v for k, v in overrides.items()}
    return [{**base, **overrides, **r} for r in results or [{}]]  # no results: one row, NaN metrics


def _collect(root: Path, runs: list[Path]) -> pd.DataFrame:
    rows = [row for run in runs for row in _rows_of(run, run.relative_to(root).as_posix())]
    df = pd.DataFrame(rows, columns=None if rows else HEAD + TAIL)
    keys = [c for c in df.columns if c not in HEAD + TAIL]  # first-seen order across runs
    df = df.reindex(columns=HEAD + keys + TAIL)
    df[keys] = df[keys].fillna("").astype(str)  # a run without a key ran with that key's default
    for col in ("seed", "n", "steps"):
        df[col] = pd.to_numeric(df[col], errors="coerce").round().astype("Int64")  # NaN-safe, writes "1" not "1.0"
    for col in ("noise_std", "mean_rel_dev", "std_rel_dev", "train_seconds"):
        df[col] = pd.to_numeric(df[col], errors="coerce").astype(float)
    return df


def collect(paths) -> pd.DataFrame:
    """Long form: one row per job x split x noise_std x parameter; a failed or unreadable job is one row with
    NaN metrics. Columns: run, status, error, seed, one per override key (strings, "" if unset), split,
    noise_std, parameter, mean_rel_dev, std_rel_dev, n, steps, train_seconds."""
    return _collect(*_resolve(paths))


def override_keys(df: pd.DataFrame) -> list[str]:
    return [c for c in df.columns if c not in HEAD + TAIL]


def row_keys(df: pd.DataFrame) -> list[str]:
    """The swept keys other than seed: those whose values differ between runs. Runs whose configuration is
    unknown (unreadable, no .hydra) are left out of this choice so they cannot make every key look swept."""
    runs = df.drop_duplicates("run")
    known = runs[runs.status != "unreadable"]
    runs = known if len(known) else runs
    return [k for k in override_keys(df) if runs[k].nunique() > 1]


def _sort_key(values) -> list[tuple]:
    # numbers in numeric order ("9" before "10"), then text
    out = []
    for v in values if isinstance(values, tuple) else (values,):
        try:
            f = float(v)
            out.append((0, f, "") if not math.isnan(f) else (1, 0.0, str(v)))
        except (TypeError, ValueError):
            out.append((1, 0.0, str(v)))
    return out


def summary_table(df: pd.DataFrame, split: str = "test", metric: str = "mean_rel_dev") -> pd.DataFrame:
    """Rows: the swept values other than seed ("all" if none vary). Columns (noise_std, parameter, stat):
    stat "mean" and "std" (ddof=1) of the metric over the completed seeds; then ("n_seeds", "", "") counting
    completed runs and ("n_failed", "", "") counting the others (failed, unreadable)."""
    if metric not in METRICS:
        raise ValueError(f"metric={metric!r} is not one of {list(METRICS)}")
    keys = row_keys(df)
    if not keys:
        df, keys = df.assign(**{NO_KEYS: NO_KEYS}), [NO_KEYS]
    runs = df.drop_duplicates("run")
    done = runs.status == "completed"
    counts = pd.DataFrame({"n_seeds": done, "n_failed": ~done}).groupby([runs[k] for k in keys]).sum().astype(int)
    counts.columns = pd.MultiIndex.from_tuples([(c, "", "") for c in counts.columns])

    sub = df[(df.status == "completed") & (df.split == split)]
    names = ["noise_std", "parameter", "stat"]
    if len(sub):
        stats = sub.groupby(keys + names[:2])[metric].agg(mean="mean", std=lambda s: s.std(ddof=1))
        cells = stats.stack().unstack(names[:2] + [-1]).sort_index(axis=1)  # noise, parameter, mean|std
        cells.columns = cells.columns.set_names(names)
    else:
        cells = pd.DataFrame(index=counts.index, columns=pd.MultiIndex.from_tuples([], names=names))
    table = pd.concat([cells.reindex(counts.index), counts], axis=1)
    table.columns = table.columns.set_names(names)
    return table.iloc[sorted(range(len(table)), key=lambda i: _sort_key(table.index[i]))]


def _number(v: float, as_percent: bool) -> str:
    return f"{100 * v:.2f}" if as_percent else f"{v:.4f}"


def to_markdown(table: pd.DataFrame, as_percent: bool = True) -> str:
    """A GitHub markdown table: one column per (noise, parameter) with "mean ± std" over seeds (std, ddof=1,
    omitted for a single seed), then the counts of completed seeds and failed jobs."""
    cells = [c[:2] for c in table.columns if c[2] == "mean"]
    unit = " [%]" if as_percent else ""
    header = [str(n) for n in table.index.names] + [f"noise {n:g} {p}{unit}" for n, p in cells] + ["seeds", "failed"]
    lines = ["| " + " | ".join(header) + " |",
             "|" + "|".join([" --- "] * table.index.nlevels + [" ---: "] * (len(header) - table.index.nlevels)) + "|"]
    for label, row in table.iterrows():
        out = [str(v) if v != "" else "(default)" for v in (label if isinstance(label, tuple) else (label,))]
        for n, p in cells:
            mean, std = row[(n, p, "mean")], row[(n, p, "std")]
            text = "n/a" if pd.isna(mean) else _number(mean, as_percent)
            out.append(text if pd.isna(std) or pd.isna(mean) else f"{text} ± {_number(std, as_percent)}")
        out += [str(int(row[("n_seeds", "", "")])), str(int(row[("n_failed", "", "")]))]
        lines.append("| " + " | ".join(v.replace("|", "\\|") for v in out) + " |")
    return "\n".join(lines) + "\n"


def _write_atomic(path: Path, write) -> None:
    """write(tmp) then rename: a reader (or a concurrent summary from another job) never sees half a file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _markdown_report(df: pd.DataFrame, table: pd.DataFrame, split: str, metric: str, keys: list[str]) -> str:
    runs = df.drop_duplicates("run")
    bad = runs[runs.status != "completed"]
    lines = [f"# Sweep summary: {METRICS[metric]} on the {split} split [%]", "",
             f"{len(runs)} runs: {len(runs) - len(bad)} completed, {len(bad)} failed or unreadable. "
             f"Cells: mean ± sample standard deviation (ddof=1) over seeds.", "", to_markdown(table), "## Failed jobs", ""]
    for _, r in bad.iterrows():
        config = ", ".join([f"{k}={r[k]}" for k in keys if r[k] != ""] + ([f"seed={r.seed}"] if pd.notna(r.seed) else []))
        error = " ".join(str(r.error).split()) if pd.notna(r.error) else "no error recorded"
        lines.append(f"- `{r.run}` ({config}): {r.status}: {error}")
    if bad.empty:
        lines.append("None.")
    return "\n".join(lines) + "\n"


def _curves(df: pd.DataFrame, root: Path, keys: list[str]) -> pd.DataFrame:
    """Each completed run's curves.csv, labelled by its table row; a missing or corrupt file is skipped."""
    frames = []
    for _, r in df[df.status == "completed"].drop_duplicates("run").iterrows():
        try:
            c = pd.read_csv(root / r.run / "curves.csv")
        except (OSError, ValueError):
            continue
        frames.append(c.assign(run=r.run, label=sweep_plots.row_label(keys, [r[k] for k in keys])))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def write_summary(sweep_dir, paths=None, split: str = "test", metric: str = "mean_rel_dev",
                  figures: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Write sweep_dir/summary.csv (long form), summary.md (table and failed jobs) and figures/ built from the
    run records found under paths (default: sweep_dir). Returns (long form, table)."""
    sweep_dir = Path(sweep_dir)
    root, runs = _resolve(sweep_dir if paths is None else paths)
    if not runs:
        raise ValueError(f"paths={paths if paths is not None else str(sweep_dir)!r} hold no run ({RECORD})")
    df = _collect(root, runs)
    table = summary_table(df, split=split, metric=metric)
    keys = row_keys(df)
    sweep_dir.mkdir(parents=True, exist_ok=True)
    _write_atomic(sweep_dir / "summary.csv", lambda p: df.to_csv(p, index=False))
    _write_atomic(sweep_dir / "summary.md",
                  lambda p: p.write_text(_markdown_report(df, table, split, metric, keys), encoding="utf-8"))
    if figures:
        out = sweep_dir / "figures"
        out.mkdir(exist_ok=True)
        if any(c[2] == "mean" for c in table.columns):  # at least one completed run
            _write_atomic(out / "robustness.png",
                          lambda p: sweep_plots.robustness_figure(table, p, metric=metric, split=split))
        curves = _curves(df, root, keys)
        if len(curves):  # runs record curves on train and test only: other splits fall back to test
            on = split if (curves["split"] == split).any() else "test"
            _write_atomic(out / "learning_curves_compared.png",
                          lambda p: sweep_plots.learning_curves_compared(curves, p, metric=metric, split=on))
    return df, table
