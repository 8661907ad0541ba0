"""The targets of the label-free anchored estimator against the classical fits, as experiment=anchored's report states
them (docs/results_notes.md, "The anchored estimator"): per fault, noise level and parameter, the label-free
estimator's mean relative deviation, the reference it is held to, their ratio with a paired bootstrap interval
over recordings, the Wilcoxon signed-rank test of the pairs, and whether the goal is met.

Pairs: every run of one seed evaluates the same test windows with the same noise (the data module's seeded draws),
so an estimator's deviation on a recording pairs with another's on that recording and seed. The interval resamples
those pairs, pooled over the seeds, with a fixed seed of its own: the same runs give the same table.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from hybrid_sysid.report.collect import load_predictions, load_runs
from hybrid_sysid.report.markdown import markdown_table
from hybrid_sysid.report.stats import CONFIDENCE, wilcoxon_p
from hybrid_sysid.runs.layout import PREDICTIONS

CANDIDATES = ("anchored_cross_segment", "anchored_partner", "anchored_label_free")  # the label-free anchored ones
CLASSICAL = ("ls", "eiv", "eiv_map", "eiv_bayes")  # the fits without a network, fixes aside
READ = (*CANDIDATES, *CLASSICAL, "eiv_fix")  # the estimators whose predictions the table pairs
EXACT = 1e-4  # 0.01%: "exact" on clean consistent windows
RESAMPLES = 2000


@dataclass(frozen=True)
class Goal:
    """At ``noise``: the candidate's error at most ``factor`` times the reference's (``reference`` an estimator,
    "best classical" the classical fit with the lowest mean, or None for an absolute ``limit``)."""

    noise: float
    reference: str | None
    factor: float = 1.0
    limit: float | None = None
    strict: bool = False


CLEAN_GOALS = {
    "p1": [Goal(0.0, None, limit=EXACT), Goal(0.003, "eiv", 1.03), Goal(0.01, "eiv", 1.03),
           Goal(0.03, "eiv_map"), Goal(0.1, None, limit=0.185)],
    "p2": [Goal(0.0, None, limit=EXACT), Goal(0.003, "eiv", 1.03), Goal(0.01, "eiv", 1.03),
           Goal(0.03, "eiv_map"), Goal(0.1, "best classical", strict=True)],
}  # fmt: skip


def _goals(fault: str, levels) -> dict[str, list[Goal]]:
    if fault == "clean":
        return CLEAN_GOALS
    return {p: [Goal(n, "eiv_fix", 1.1) for n in levels] for p in ("p1", "p2")}


def _paired(devs: pd.DataFrame, a: str, b: str) -> tuple[np.ndarray, np.ndarray]:
    """The deviations of estimators a and b on the (seed, recording) pairs both evaluated."""
    wide = devs[devs.estimator.isin([a, b])].pivot_table(
        index=["seed", "recording"], columns="estimator", values="rel_dev", aggfunc="first"
    )
    if a not in wide or b not in wide:
        return np.empty(0), np.empty(0)
    wide = wide[[a, b]].dropna()
    return wide[a].to_numpy(), wide[b].to_numpy()


def ratio_interval(a: np.ndarray, b: np.ndarray, seed: int = 0) -> tuple[float, float]:
    """The CONFIDENCE percentile interval of mean(a) / mean(b) over RESAMPLES bootstrap draws of the pairs."""
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(a), size=(RESAMPLES, len(a)))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = a[idx].mean(axis=1) / b[idx].mean(axis=1)
    tail = (1 - CONFIDENCE) / 2 * 100
    low, high = np.nanpercentile(ratios, [tail, 100 - tail])
    return float(low), float(high)


def target_rows(devs: pd.DataFrame, candidate: str) -> list[list[str]]:
    """The table's rows for one candidate; ``devs``: run, estimator, fault, seed, noise_std, recording,
    parameter, rel_dev at K = 1."""
    rows = []
    for fault in dict.fromkeys(devs.fault):
        sub = devs[devs.fault == fault]
        levels = sorted(set(sub.noise_std))
        for param, goals in _goals(fault, levels).items():
            for goal in goals:
                here = sub[(sub.parameter == param) & np.isclose(sub.noise_std, goal.noise)]
                mine = here[here.estimator == candidate]
                if mine.empty:
                    continue
                value = mine.rel_dev.mean()
                rows.append(_row(fault, goal, param, candidate, value, here))
    return [r for r in rows if r is not None]


def _rows_of(here, estimator):
    """An estimator's rows of a cell."""
    return here[here.estimator == estimator]


def _row(fault, goal: Goal, param, candidate, value, here) -> list[str] | None:
    pct = lambda v: f"{100 * v:.2f}"  # noqa: E731
    head = [fault, f"{goal.noise:g}", param, pct(value)]
    if goal.reference is None:
        met = value <= goal.limit
        ratio = "-"
        if goal.limit > EXACT:  # the value over the limit, with the interval of its mean over the recordings
            a = _rows_of(here, candidate).drop_duplicates(["seed", "recording"]).rel_dev.to_numpy()
            low, high = ratio_interval(a, np.full(len(a), goal.limit))
            ratio = f"{value / goal.limit:.3f} [{low:.3f}, {high:.3f}]"
        return [
            *head,
            "-",
            "-",
            ratio,
            f"<= {pct(goal.limit)}%",
            "yes" if met else "**no**",
            "-",
            str(len(_rows_of(here, candidate))),
        ]
    reference = goal.reference
    if reference == "best classical":
        means = {e: here[here.estimator == e].rel_dev.mean() for e in CLASSICAL if (here.estimator == e).any()}
        if not means:
            return None
        reference = min(means, key=means.get)
    a, b = _paired(here, candidate, reference)
    if not len(a):
        return None
    if goal.noise == 0 and b.mean() <= EXACT:  # where the fixed fit is exact, so must the candidate be
        met = a.mean() <= EXACT
        return [*head, reference, pct(b.mean()), "-", f"<= {pct(EXACT)}%", "yes" if met else "**no**", "-", str(len(a))]
    ratio = a.mean() / b.mean() if b.mean() > 0 else float("inf")
    low, high = ratio_interval(a, b)
    met = ratio < goal.factor if goal.strict else ratio <= goal.factor
    sign = "<" if goal.strict else "<="
    return [
        *head,
        reference,
        pct(b.mean()),
        f"{ratio:.3f} [{low:.3f}, {high:.3f}]",
        f"{sign} {goal.factor:g}x",
        "yes" if met else "**no**",
        f"{wilcoxon_p(a, b):.2g}",
        str(len(a)),
    ]


def damaged_predictions(root: Path, df: pd.DataFrame, devs: pd.DataFrame) -> dict[str, str]:
    """Run -> why its predictions.csv cannot be paired, for each completed run of the table's estimators whose
    file is missing or unreadable, does not end its last line (cut within a row, whose numbers may be cut too), or
    holds another count of test recordings at K = 1 than its record's ``n`` (cut by its last rows). ``devs``:
    load_predictions at K = 1, with the runs' estimator."""
    read = (df.status == "completed") & (df.split == "test") & (df.windows == 1) & df.estimator.isin(READ)
    test = df[read.fillna(False).astype(bool) & df.n.notna()]
    expected = test.groupby(["run", "noise_std"]).n.max()
    found = devs.groupby(["run", "noise_std"]).recording.nunique()
    damaged = {}
    for run in dict.fromkeys(test.run):
        path = root / run / PREDICTIONS
        if not path.is_file():
            damaged[run] = "is missing"
        elif not _ends_its_last_line(path):
            damaged[run] = "ends within a row (cut)"
        elif run not in found.index.get_level_values("run"):
            damaged[run] = "cannot be read, or holds no test rows at K = 1"
        else:
            for noise, n in expected[run].items():
                k = found[run].get(noise, 0)
                if k != n:
                    damaged[run] = f"holds {k} test recordings at noise {noise:g} where its record counts {n}"
                    break
    return damaged


def _ends_its_last_line(path: Path) -> bool:
    """pandas ends every row of the file it writes with a newline: a file without one at its end was cut."""
    try:
        with path.open("rb") as f:
            f.seek(-1, 2)
            return f.read(1) == b"\n"
    except OSError:  # empty, or unreadable: the count says the rest
        return True


def targets_markdown(paths) -> str:
    """The targets table of the sweeps at ``paths`` (an empty string when they hold no label-free anchored run
    beside the classical fits)."""
    root, df = load_runs(paths)
    if "estimator" not in df or not df.estimator.isin(CANDIDATES).any() or not df.estimator.isin(CLASSICAL).any():
        return ""
    runs = df.drop_duplicates("run").set_index("run")
    devs = load_predictions(root, df)
    devs = devs[devs.windows == 1]
    for key in ("estimator", "fault", "seed"):
        default = "clean" if key == "fault" else ""
        devs[key] = devs.run.map(runs[key]) if key in runs else default
    # a cut file would pair fewer recordings in silence (or a number cut short): the run is left out, and named
    damaged = damaged_predictions(root, df, devs)
    devs = devs[~devs.run.isin(list(damaged))]
    notes = "".join(
        f"- `{run}/{PREDICTIONS}` {why}: that run is left out of the targets.\n" for run, why in damaged.items()
    )
    # a job copied under another number, or a row repeated, is one recording: the value and the pairs count it once
    devs = devs.drop_duplicates(["estimator", "fault", "seed", "noise_std", "parameter", "recording"])
    tables = {c: target_rows(devs, c) for c in CANDIDATES if (devs.estimator == c).any()}
    tables = {c: rows for c, rows in tables.items() if rows}
    if not tables:
        return (
            f"No targets of the label-free anchored estimators: the predictions they pair are damaged.\n\n{notes}"
            if notes
            else ""
        )
    header = ["fault", "noise", "parameter", "value [%]", "reference", "its value [%]",
              f"ratio [{CONFIDENCE:.0%} interval]", "goal", "met", "Wilcoxon p", "recordings"]  # fmt: skip
    text = (
        "Targets of the label-free anchored estimators (K = 1; the mean over seeds and recordings; the ratio's "
        "interval a paired bootstrap over recordings; p the Wilcoxon signed-rank test of the pairs; recordings: the "
        "pairs, or the candidate's recordings, over all seeds).\n\n"
    )
    text += f"{notes}\n" if notes else ""
    for c, rows in tables.items():
        text += f"`estimator={c}`\n\n" + markdown_table(header, rows, n_left=3) + "\n\n"
    return text.rstrip() + "\n"
