"""The paper's reported figures (Sokolowski et al. 2020) beside ours: reproduction.md, and the comparison section
of a results page. It places numbers side by side and draws no conclusion from them; the reading of the tables is
written by hand (docs/results_notes.md).

The paper reports one training per objective, after 500,000 Adam steps, as mu = mean and sigma = standard deviation
of the relative deviation |p - p_pred| / p (eq. 24) over the recordings of a split; no seeds, no repeats. Each
figure below is cited by section and figures. Figures it does not report are absent here, not guessed: it gives no
sigma at noise 0.01, no figure per parameter for the hybrid objective at noise 0.01, and nothing on the training
split at noise 0.01 (it trains and evaluates training data clean only). Its summaries "4-8%" (labelled) and
"8-10%" (hybrid), at the end of sec. 3.2 and for the training split in sec. 3.3, restate the point figures.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from hybrid_sysid.core.files import ESCAPED, write_atomic
from hybrid_sysid.model.metrics import relative_deviation
from hybrid_sysid.report.collect import load_runs, natural_key, row_keys, run_choices
from hybrid_sysid.report.markdown import markdown_table
from hybrid_sysid.report.protocol import protocol
from hybrid_sysid.report.stats import K_LEVEL

NOISE_LEVELS = (0.0, 0.01)  # the paper's: clean, and N(0, 0.01) added to both channels (sec. 3.3)
PAPER_SPLITS = ("train", "test")  # it has no validation split
OBJECTIVES = ("labelled", "hybrid")  # eq. 18 (J_L) and eq. 23 (J_U)


class PaperFigure(NamedTuple):
    """One reported figure as the paper prints it, in percent: mu ("6.2"; a range "26-28"; "≈16" for "around
    16%") and sigma, the std over the recordings ("not reported" where it gives none)."""

    where: str
    mu: str
    sigma: str = "not reported"


_L_TRAIN = "sec. 3.1, text on Figs. 6-9 (training set, step 500,000)"
_L_TEST = "sec. 3.1, text on Figs. 10-13 (test set, step 500,000)"
_U_TRAIN = "sec. 3.2, text on Figs. 14-17 (training set, step 500,000)"
_U_TEST = "sec. 3.2, text on Figs. 18-21 (test set, step 500,000)"
_L_NOISY = (
    'sec. 3.3, text on Figs. 22-25: "For both p1 and p2 the test deviation lies between 26-28% '
    'throughout the training process"'
)
_U_NOISY = (
    'sec. 3.3, text on Figs. 26-29: "The noisy test data results in a relative deviation of around '
    '16%", one figure for both parameters'
)

# (objective, split, noise_std, parameter) -> the paper's figure
PAPER: dict[tuple[str, str, float, str], PaperFigure] = {
    ("labelled", "train", 0.0, "p1"): PaperFigure(_L_TRAIN, "6.2", "9.1"),
    ("labelled", "train", 0.0, "p2"): PaperFigure(_L_TRAIN, "4.3", "8.3"),
    ("labelled", "test", 0.0, "p1"): PaperFigure(_L_TEST, "6.0", "7.9"),
    ("labelled", "test", 0.0, "p2"): PaperFigure(_L_TEST, "4.2", "8.4"),
    ("hybrid", "train", 0.0, "p1"): PaperFigure(_U_TRAIN, "10.2", "13.1"),
    ("hybrid", "train", 0.0, "p2"): PaperFigure(_U_TRAIN, "8.2", "13.1"),
    ("hybrid", "test", 0.0, "p1"): PaperFigure(_U_TEST, "9.7", "12.7"),
    ("hybrid", "test", 0.0, "p2"): PaperFigure(_U_TEST, "7.6", "12.7"),
    ("labelled", "test", 0.01, "p1"): PaperFigure(_L_NOISY, "26-28"),
    ("labelled", "test", 0.01, "p2"): PaperFigure(_L_NOISY, "26-28"),
    ("hybrid", "test", 0.01, "p1"): PaperFigure(_U_NOISY, "≈16"),
    ("hybrid", "test", 0.01, "p2"): PaperFigure(_U_NOISY, "≈16"),
}

# label -> the paper's protocol (where it says so); the rows of the protocol table, matched to protocol() labels
PAPER_PROTOCOL: dict[str, str] = {
    "steps": "500,000 (sec. 3.1-3.3, figure captions)",
    "model": "sec. 2.4: Conv1d 100 x 50 tanh, Conv1d 100 x 10, dense 100, 10, 2, absolute value",
    "optimiser": "Adam, lr 0.001, batch 100 (sec. 3.1, text on Figs. 6-9; the same in sec. 3.2)",
    "data": "100 roads x 100 masses x 6000 steps; 80 training roads, 20 test roads (sec. 2.3)",
    "seat masses": "m3 uniform on the integers 50-200 kg (sec. 2.3)",
    "dt": "not stated (h = (t_N - t_0) / N only, sec. 2.3)",
    "speed": "not stated",
    "window": "500 steps (sec. 2.4)",
    "measurement": "eq. 12: accelerations from the states at step k",
    "test noise std": "clean, and N(0, 0.01) on both channels (eq. 25); the captions of Figs. 22-29 write sigma = 0.01",
    "training noise std": "none: trained on clean data (sec. 3.3)",
    "seeds": "one training per objective; no seeds or repeats reported",
    "training time per run": "not stated",
    "test recordings": "2000 (20 roads x 100 masses; sec. 3.1, text on Figs. 10-13); training: 8000",
    "windows per test recording": "not stated",
}


def constant_guess(m3_min: int = 50, m3_max: int = 200) -> float:
    """The lowest mean relative deviation a single constant prediction can score when m3 is uniform on the
    integers [m3_min, m3_max]: for p = c / m3, |p - q| / p = |1 - k m3| with k = q / c, minimised over k (a
    weighted median, found among the candidates k = 1 / m3). Same for p1 and p2, so c = 1 here."""
    m = np.arange(m3_min, m3_max + 1, dtype=np.float64)
    return float(min(relative_deviation(1 / mk, 1 / m).mean() for mk in m))


LEGEND = (
    'Paper: mu as printed ("26-28": the paper gives only that range; "≈16": "around 16%", one figure '
    "for both parameters). Ours: mean ± sample std (ddof=1) over seeds of each run's mean relative deviation, "
    "without ± for a single seed. σ: std of the relative deviation over the recordings of the split (the "
    "paper's sigma; ours: mean over seeds). Rows the paper reports and we did not run leave our other keys "
    "blank. Noise levels are standard deviations in m/s^2; our other levels, if any, are in summary.md. "
    f"For scale: the best constant prediction for the paper's seat masses scores {100 * constant_guess():.1f}% "
    "on either parameter."
)
PARAMETERS = tuple(dict.fromkeys(p for *_, p in PAPER))  # ("p1", "p2"), read off the table above
_STATS = [f"{p} {s}" for p in PARAMETERS for s in ("mean", "sd", "sigma")]


def reproduction_table(df: pd.DataFrame, root: Path) -> pd.DataFrame:
    """One row per (split, noise_std, objective, [other swept keys], [K]) our completed runs have at the paper's
    splits and noise levels, and one row (other keys blank) per (split, noise_std, objective) the paper reports
    and we did not run; in the paper's order, its objectives first. Columns per parameter p: "p mean" and "p sd"
    (mean and sample std over seeds of each run's mean relative deviation), "p sigma" (mean over seeds of each
    run's std over recordings); and "seeds"."""
    done = df[(df.status == "completed") & df.split.isin(PAPER_SPLITS) & df.noise_std.isin(NOISE_LEVELS)].copy()
    # a run that did not override the objective ran with its config-group choice
    given = done["objective"] if "objective" in done else pd.Series("", index=done.index)
    chosen = {r: run_choices(root / r).get("objective", "") for r in done.run[given == ""].unique()}
    done["objective"] = given.where(given != "", done.run.map(chosen))
    extra = [k for k in row_keys(df) if k != "objective"]
    if len(done) and done.groupby(["objective", *extra]).windows.nunique().max() > 1:
        done, extra = done.assign(**{K_LEVEL: done.windows}), extra + [K_LEVEL]
    keys = ["split", "noise_std", "objective", *extra]
    parts = []
    if len(done):
        g = done.groupby(keys + ["parameter"])
        stats = pd.concat(
            {"mean": g.mean_rel_dev.mean(), "sd": g.mean_rel_dev.std(ddof=1), "sigma": g.std_rel_dev.mean()}, axis=1
        ).unstack("parameter")
        stats.columns = [f"{p} {s}" for s, p in stats.columns]
        parts.append(stats.assign(seeds=done.groupby(keys).run.nunique()).reset_index())
    ran = set(zip(done.split, done.noise_std, done.objective))
    missing = sorted({(s, n, o) for o, s, n, _ in PAPER if (s, n, o) not in ran})
    if missing:
        parts.append(
            pd.DataFrame(
                [
                    {"split": s, "noise_std": n, "objective": o, **dict.fromkeys(extra, ""), "seeds": 0}
                    for s, n, o in missing
                ]
            )
        )
    rows = pd.concat(parts, ignore_index=True).reindex(columns=keys + _STATS + ["seeds"])
    objectives = list(OBJECTIVES) + sorted(set(rows.objective) - set(OBJECTIVES))
    order = sorted(
        range(len(rows)),
        key=lambda i: (
            PAPER_SPLITS.index(rows.split.iloc[i]),
            rows.noise_std.iloc[i],
            objectives.index(rows.objective.iloc[i]),
            natural_key(tuple(rows[extra].iloc[i])),
        ),
    )
    return rows.iloc[order].reset_index(drop=True)


def comparison_markdown(df: pd.DataFrame, root: Path) -> str:
    """The paper's figures beside ours as a markdown table (see reproduction_table), in percent."""
    rt = reproduction_table(df, root)
    extra = [c for c in rt.columns if c not in ["split", "noise_std", "objective", "seeds", *_STATS]]
    header = [
        "split",
        "noise std",
        "objective",
        *extra,
        *(f"{p} {w}" for p in PARAMETERS for w in ("paper", "ours")),
        *(f"{p} σ {w}" for p in PARAMETERS for w in ("paper", "ours")),
        "seeds",
    ]
    pct = lambda v: "not run" if pd.isna(v) else f"{100 * v:.2f}"  # noqa: E731
    rows = []
    for _, r in rt.iterrows():
        paper = {p: PAPER.get((r.objective, r.split, r.noise_std, p)) for p in PARAMETERS}
        cells = [r.split, f"{r.noise_std:g}", r.objective or "(default)", *(str(r[k]) for k in extra)]
        for p in PARAMETERS:
            ours = pct(r[f"{p} mean"]) + ("" if pd.isna(r[f"{p} sd"]) else f" ± {pct(r[f'{p} sd'])}")
            cells += [paper[p].mu if paper[p] else "not reported", ours]
        for p in PARAMETERS:
            cells += [paper[p].sigma if paper[p] else "not reported", pct(r[f"{p} sigma"])]
        rows.append(cells + [str(int(r.seeds))])
    return markdown_table(header, rows, 3 + len(extra))


def reproduction_markdown(paths) -> str:
    """reproduction.md's text for the runs at or below paths: the protocol (paper and ours), the comparison table,
    and where each of the paper's figures is."""
    root, df = load_runs(paths)
    proto = protocol(df, root)
    n_runs, n_done = df.run.nunique(), df[df.status == "completed"].run.nunique()
    shown = ", ".join(f"`{p}`" for p in ([paths] if isinstance(paths, (str, Path)) else paths))
    lines = [
        "# Reproduction: Sokolowski et al. (2020), the paper's figures beside ours",
        "",
        f"Runs: {n_runs} under {shown} ({n_done} completed, {n_runs - n_done} failed or unreadable).",
        "",
        "## Protocol",
        "",
        markdown_table(
            ["", "paper", "ours"],
            [[label, paper, proto.get(label, "not recorded")] for label, paper in PAPER_PROTOCOL.items()],
            3,
        ),
        "## Mean relative deviation [%]",
        "",
        comparison_markdown(df, root),
        LEGEND,
        "",
        "Where the paper's figures are:",
        "",
    ]
    lines += [
        f"- {w}" for w in dict.fromkeys(f"{o}, {s}, noise {n:g}: {fig.where}" for (o, s, n, _), fig in PAPER.items())
    ]
    return "\n".join(lines) + "\n"


def write_reproduction(out_dir, paths=None) -> str:
    """Write out_dir/reproduction.md from the runs under paths (default: out_dir); returns its text."""
    out_dir = Path(out_dir)
    text = reproduction_markdown(out_dir if paths is None else paths)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_atomic(out_dir / "reproduction.md", lambda p: p.write_text(text, encoding="utf-8", errors=ESCAPED))
    return text
