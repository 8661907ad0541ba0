"""What the runs of a sweep actually did, read from their records and Hydra's files (.hydra/config.yaml, the
group choices in .hydra/hydra.yaml): model, optimiser, data size, dt, measurement, steps, seeds, noise levels.
A value that differs between runs is listed with every value seen ("1000 / 2000")."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from hybrid_sysid.report.collect import config_value, run_choices, run_config


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list):
        return ", ".join(_fmt(x) for x in v)
    return str(v)


def _describe(cfg: dict, choices: dict) -> dict[str, str | None]:
    g = lambda k: config_value(cfg, k)  # noqa: E731
    # a baseline (baseline=) runs instead of the model, whose group keeps its default
    group = "baseline" if g("baseline._target_") else "model"
    target = str(g("baseline._target_" if group == "baseline" else "model.net._target_") or "").rsplit(".", 1)[-1]
    choice = choices.get(group)
    d = {"model": f"{choice} ({target})" if choice and target else choice or target or None}
    if group == "model" and g("model.optim.name") is not None:
        d["optimiser"] = (
            f"{g('model.optim.name')}, lr {_fmt(g('model.optim.lr'))}, {g('model.optim.schedule')} "
            f"schedule, batch {g('model.batch_size')}"
        )
    if g("data.n_roads") is not None:
        d["data"] = (
            f"{g('data.n_roads')} roads x {g('data.n_masses')} masses x {g('data.n_steps')} steps "
            f"(train fraction {_fmt(g('data.train_fraction'))} of the roads, validation "
            f"{_fmt(g('data.val_fraction'))} of those)"
        )
    if isinstance(g("data.dt"), (int, float)):
        d["dt"] = f"{1000 * g('data.dt'):g} ms"
    for key, label in (
        ("data.speed", "speed"),
        ("data.window", "window"),
        ("data.measurement", "measurement"),
        ("noise.eval_std", "test noise std"),
        ("noise.train_std", "training noise std"),
    ):
        if g(key) is not None:
            d[label] = _fmt(g(key)) + {"speed": " m/s", "window": " steps"}.get(label, "")
    if isinstance(g("noise.train_std_max"), (int, float)):  # a range: each training window draws its own std
        d["training noise std"] = (
            f"{_fmt(g('noise.train_std'))}-{_fmt(g('noise.train_std_max'))} (log-uniform per training window)"
        )
    if g("data.m3_min") is not None:
        d["seat masses"] = f"m3 uniform on the integers {g('data.m3_min')}-{g('data.m3_max')} kg"
    return d


def _join(values) -> str | None:
    seen = [v for v in dict.fromkeys(values) if v is not None]
    return " / ".join(seen) if seen else None


def _range(values) -> str:
    """'3', '0-2' (consecutive integers) or '100, 500'; 'none' when there is no value."""
    values = sorted({int(v) for v in values if pd.notna(v)})
    if len(values) <= 1:
        return str(values[0]) if values else "none"
    if values == list(range(values[0], values[-1] + 1)):
        return f"{values[0]}-{values[-1]}"
    return ", ".join(map(str, values))


def protocol(df: pd.DataFrame, root: Path) -> dict[str, str]:
    """Label -> value over the completed runs of df (collect's long form; run names relative to root):
    the config fields above, plus steps, seeds, training seconds, test recordings and windows per recording."""
    runs = df[df.status == "completed"].drop_duplicates("run")
    described = [_describe(run_config(root / r), run_choices(root / r)) for r in runs.run]
    labels = list(dict.fromkeys(k for d in described for k in d))
    out = {k: _join(d.get(k) for d in described) for k in labels}
    out = {k: v for k, v in out.items() if v is not None}
    out["steps"] = _range(runs.steps)
    out["seeds"] = _range(runs.seed)
    if runs.train_seconds.notna().any():
        out["training time per run"] = f"{runs.train_seconds.mean():.0f} s on average (evaluations excluded)"
    test = df[(df.status == "completed") & (df.split == "test")]
    if len(test):
        out["test recordings"] = _range(test.n)
        out["windows per test recording"] = _range(test.windows)
    return out


def one_line(p: dict[str, str]) -> str:
    """A compact protocol sentence for a results page."""
    keys = ["model", "optimiser", "steps", "seeds", "data", "dt", "measurement", "training noise std", "test noise std"]
    return "; ".join(f"{k} {p[k]}" for k in keys if k in p) + "."
