"""Sweep summary built from run records on disk alone: long-form table, comparison table, markdown, figures.

The spread over seeds is the sample standard deviation (ddof=1) everywhere; with a single seed it is NaN and the
markdown shows no "±". Override values stay the strings Hydra recorded, so "0.002" and "2e-3" stay distinct rows.
A results row's "windows" (K, test-time averaging over K windows per recording) is 1 when absent; when rows that
share their swept values hold more than one K, K becomes a row level of the table. Marks (best row, gap beyond
the seed spread) and the LaTeX form: see tables.py.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Iterable

import pandas as pd

from hybrid_sysid.report import sweep_figures
from hybrid_sysid.files import write_atomic
from hybrid_sysid.records import RECORD
from hybrid_sysid.report.tables import K_LEVEL, compared_level, to_latex, to_markdown  # noqa: F401 (re-export)

METRICS = {"mean_rel_dev": "mean relative deviation", "std_rel_dev": "std of relative deviation"}
HEAD = ["run", "status", "error", "seed"]
TAIL = ["split", "noise_std", "windows", "parameter", "mean_rel_dev", "std_rel_dev", "n", "steps", "train_seconds"]
RESULT = ["split", "noise_std", "parameter", "mean_rel_dev", "std_rel_dev", "n"]  # required in a results row
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


def _default_of(run_dir: Path, key: str) -> str:
    """What a run used for a key it did not override: its config-group choice or its config value, as Hydra
    saved them under .hydra/; "" when neither is there."""
    from hybrid_sysid.report.protocol import _get, run_choices, run_config

    choices = run_choices(run_dir)
    value = choices[key] if key in choices else _get(run_config(run_dir), key)
    return "" if value is None else str(value)


def _rows_of(run_dir: Path, name: str) -> list[dict]:
    try:
        rec = json.loads((run_dir / RECORD).read_text())
        base = {"run": name, "status": str(rec["status"]), "error": rec.get("error"), "seed": rec.get("seed"),
                "steps": rec.get("steps"), "train_seconds": rec.get("train_seconds")}
        overrides = _parse_overrides(rec.get("overrides") or [])
        results = [{**{k: r[k] for k in RESULT}, "windows": r.get("windows", 1)} for r in rec.get("results") or []]
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
    df[keys] = df[keys].fillna("").astype(str)
    # a run without a key ran with that key's default: read it from the run's saved config, so sweeps merged
    # with other sweeps land in the right rows ("" only when the run dir has no .hydra/)
    by_name = {run.relative_to(root).as_posix(): run for run in runs}
    for key in keys:
        blank = df[key] == ""
        for name in df.loc[blank, "run"].unique():
            df.loc[blank & (df.run == name), key] = _default_of(by_name[name], key)
    for col in ("seed", "windows", "n", "steps"):
        df[col] = pd.to_numeric(df[col], errors="coerce").round().astype("Int64")  # NaN-safe, writes "1" not "1.0"
    for col in ("noise_std", "mean_rel_dev", "std_rel_dev", "train_seconds"):
        df[col] = pd.to_numeric(df[col], errors="coerce").astype(float)
    return df


def collect(paths) -> pd.DataFrame:
    """Long form: one row per job x split x noise_std x windows x parameter; a failed or unreadable job is one
    row with NaN metrics. Columns: run, status, error, seed, one per override key (strings, "" if unset), split,
    noise_std, windows (1 when the record has none), parameter, mean_rel_dev, std_rel_dev, n, steps,
    train_seconds."""
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
    """Rows: the swept values other than seed ("all" if none vary), plus a level "K" when rows sharing those
    values hold more than one windows value. Columns (noise_std, parameter, stat): stat "mean" and "std"
    (ddof=1) of the metric over the completed seeds; then ("n_seeds", "", "") counting completed runs (with a K
    level: completed runs with results at that K) and ("n_failed", "", "") counting the others (failed,
    unreadable)."""
    if metric not in METRICS:
        raise ValueError(f"metric={metric!r} is not one of {list(METRICS)}")
    keys = row_keys(df)
    if not keys:
        df, keys = df.assign(**{NO_KEYS: NO_KEYS}), [NO_KEYS]
    runs = df.drop_duplicates("run")
    done = runs.status == "completed"
    counts = pd.DataFrame({"n_seeds": done, "n_failed": ~done}).groupby([runs[k] for k in keys]).sum().astype(int)

    sub = df[(df.status == "completed") & (df.split == split)]
    rows = keys
    if len(sub) and sub.groupby(keys).windows.nunique().max() > 1:  # several K under one row: K is a level
        sub, rows = sub.assign(**{K_LEVEL: sub.windows}), keys + [K_LEVEL]
        ks = sorted(sub[K_LEVEL].dropna().unique())
        labels = [c if isinstance(c, tuple) else (c,) for c in counts.index]
        index = pd.MultiIndex.from_tuples([(*c, k) for c in labels for k in ks], names=rows)
        seeds = sub.groupby(rows).run.nunique().reindex(index).fillna(0).astype(int)
        failed = [int(counts.n_failed.iloc[i]) for i in range(len(counts)) for _ in ks]
        counts = pd.DataFrame({"n_seeds": seeds.to_numpy(), "n_failed": failed}, index=index)
    counts.columns = pd.MultiIndex.from_tuples([(c, "", "") for c in counts.columns])

    names = ["noise_std", "parameter", "stat"]
    if len(sub):
        stats = sub.groupby(rows + names[:2])[metric].agg(mean="mean", std=lambda s: s.std(ddof=1))
        cells = stats.stack().unstack(names[:2] + [-1]).sort_index(axis=1)  # noise, parameter, mean|std
        cells.columns = cells.columns.set_names(names)
    else:
        cells = pd.DataFrame(index=counts.index, columns=pd.MultiIndex.from_tuples([], names=names))
    table = pd.concat([cells.reindex(counts.index), counts], axis=1)
    table.columns = table.columns.set_names(names)
    return table.iloc[sorted(range(len(table)), key=lambda i: _sort_key(table.index[i]))]


def windows_note(df: pd.DataFrame, table: pd.DataFrame, split: str) -> str:
    """A sentence naming K when every row of the split uses the same K other than 1 (the table then has no K
    level to show it), else an empty string."""
    if K_LEVEL in table.index.names:
        return ""
    ks = df[(df.status == "completed") & (df.split == split)].windows.dropna().unique()
    return f" Windows averaged per recording: K = {int(ks[0])}." if len(ks) == 1 and ks[0] != 1 else ""


def failed_lines(df: pd.DataFrame, keys: list[str]) -> list[str]:
    """One markdown list item per failed or unreadable job (its configuration, status and error)."""
    lines = []
    for _, r in df.drop_duplicates("run").query("status != 'completed'").iterrows():
        config = ", ".join([f"{k}={r[k]}" for k in keys if r[k] != ""] + ([f"seed={r.seed}"] if pd.notna(r.seed) else []))
        error = " ".join(str(r.error).split()) if pd.notna(r.error) else "no error recorded"
        lines.append(f"- `{r.run}` ({config}): {r.status}: {error}")
    return lines


def _markdown_report(df: pd.DataFrame, table: pd.DataFrame, split: str, metric: str, keys: list[str],
                     compare: str | None = None) -> str:
    runs = df.drop_duplicates("run")
    bad = runs[runs.status != "completed"]
    lines = [f"# Sweep summary: {METRICS[metric]} on the {split} split [%]", "",
             f"{len(runs)} runs: {len(runs) - len(bad)} completed, {len(bad)} failed or unreadable. "
             f"Cells: mean ± sample standard deviation (ddof=1) over seeds.{windows_note(df, table, split)}", "",
             to_markdown(table, compare=compare), "## Failed jobs", ""]
    lines += failed_lines(df, keys) or ["None."]
    return "\n".join(lines) + "\n"


def _curves(df: pd.DataFrame, root: Path, keys: list[str]) -> pd.DataFrame:
    """Each completed run's curves.csv, labelled by its table row; a missing or corrupt file is skipped."""
    frames = []
    for _, r in df[df.status == "completed"].drop_duplicates("run").iterrows():
        try:
            c = pd.read_csv(root / r.run / "curves.csv")
        except (OSError, ValueError):
            continue
        frames.append(c.assign(run=r.run, label=sweep_figures.row_label(keys, [r[k] for k in keys])))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def write_summary(sweep_dir, paths=None, split: str = "test", metric: str = "mean_rel_dev",
                  figures: bool = True, latex: bool = False,
                  compare: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Write sweep_dir/summary.csv (long form), summary.md (table and failed jobs), with ``latex`` summary.tex,
    and figures/ built from the run records found under paths (default: sweep_dir). ``compare``: the row key
    whose values the marks compare (default: objective when swept). Returns (long form, table)."""
    sweep_dir = Path(sweep_dir)
    root, runs = _resolve(sweep_dir if paths is None else paths)
    if not runs:
        raise ValueError(f"paths={paths if paths is not None else str(sweep_dir)!r} hold no run ({RECORD})")
    df = _collect(root, runs)
    table = summary_table(df, split=split, metric=metric)
    compared_level(table, compare)  # a bad compare key fails before anything is written
    keys = row_keys(df)
    sweep_dir.mkdir(parents=True, exist_ok=True)
    write_atomic(sweep_dir / "summary.csv", lambda p: df.to_csv(p, index=False))
    write_atomic(sweep_dir / "summary.md", lambda p: p.write_text(
        _markdown_report(df, table, split, metric, keys, compare), encoding="utf-8"))
    if latex:
        caption = f"{METRICS[metric]} on the {split} split [%], mean ± std over seeds"
        write_atomic(sweep_dir / "summary.tex",
                      lambda p: p.write_text(to_latex(table, compare=compare, caption=caption), encoding="utf-8"))
    if figures:
        out = sweep_dir / "figures"
        out.mkdir(exist_ok=True)
        if any(c[2] == "mean" for c in table.columns):  # at least one completed run
            write_atomic(out / "robustness.png",
                          lambda p: sweep_figures.robustness_figure(table, p, metric=metric, split=split))
        curves = _curves(df, root, keys)
        if len(curves):  # runs record curves on train and test only: other splits fall back to test
            on = split if (curves["split"] == split).any() else "test"
            write_atomic(out / "learning_curves_compared.png",
                          lambda p: sweep_figures.learning_curves_compared(curves, p, metric=metric, split=on))
    return df, table
