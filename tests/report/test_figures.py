"""What a reader sees in each figure the project draws, asserted on the matplotlib Figure (the ``drawn`` fixture
catches it as it is saved): panels, axis labels, titles, legend, one line per row of the data given, and the
plotted numbers against a reference computed here from the fake records with pandas and numpy. The transfer bar
figure is tested with its table in test_transfer_table.py; that the PNG files are real plots, in
test_report_cli.py."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import to_rgba

from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.run_figures import write_run_figures
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.sweep_figures import tuning_figure
from hybrid_sysid.report.tables import summary_table

from evaluation_fakes import NOISES, OBJECTIVES, PARAMS, known_results, make_run

PNG = b"\x89PNG\r\n\x1a\n"


def completed(sweep) -> list[tuple[dict, Path]]:
    """(overrides as a dict, run directory) of the sweep's completed jobs, read here from metrics.json with json,
    not through the report's loader (a failed job is skipped, a corrupt record too)."""
    out = []
    for f in sorted(sweep.glob("*/metrics.json")):
        try:
            record = json.loads(f.read_text())
        except json.JSONDecodeError:
            continue
        if record["status"] == "completed":
            out.append((dict(o.split("=", 1) for o in record["overrides"]), f.parent))
    return out


def results_frame(sweep) -> pd.DataFrame:
    rows = []
    for keys, run in completed(sweep):
        rows += [{**keys, **r} for r in json.loads((run / "metrics.json").read_text())["results"]]
    return pd.DataFrame(rows)


def errorbars(ax) -> dict:
    """label -> (x, y, half length of the error bar) of each errorbar line in a panel."""
    out = {}
    for c in ax.containers:
        line, _, (bars,) = c.lines
        half = np.array([(s[1, 1] - s[0, 1]) / 2 for s in bars.get_segments()])
        out[c.get_label()] = (np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float), half)
    return out


def legend_texts(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_robustness_figure_one_line_per_objective_at_the_mean_and_std_over_seeds(sweep, drawn):
    write_summary(sweep)  # the fake sweep has a failed job and a corrupt record: neither is drawn
    assert (sweep / "figures" / "robustness.png").read_bytes()[:8] == PNG
    fig = drawn["robustness"]
    df = results_frame(sweep)
    assert sorted(df.objective.unique()) == sorted(OBJECTIVES) and df.groupby("objective").seed.nunique().eq(2).all()
    ref = df[df.split == "test"].groupby(["objective", "parameter", "noise_std"]).mean_rel_dev.agg(["mean", "std"])

    assert len(fig.axes) == len(PARAMS)  # one panel per parameter
    assert [ax.get_title() for ax in fig.axes] == PARAMS
    assert "test split" in fig.get_suptitle() and "over seeds" in fig.get_suptitle()
    assert sorted(legend_texts(fig.axes[0])) == sorted(f"objective={o}" for o in OBJECTIVES)  # names the rows
    for ax, param in zip(fig.axes, PARAMS):
        assert "noise" in ax.get_xlabel() and "relative deviation" in ax.get_ylabel()
        assert ax.get_yscale() == "log"
        assert [t.get_text() for t in ax.get_xticklabels()] == [f"{n:g}" for n in NOISES]  # the levels evaluated
        lines = errorbars(ax)
        assert len(lines) == len(OBJECTIVES)  # one line per table row
        for objective in OBJECTIVES:
            x, y, half = lines[f"objective={objective}"]
            expected = ref.loc[(objective, param)]
            np.testing.assert_allclose(x, NOISES)
            np.testing.assert_allclose(y, expected["mean"].to_numpy(), rtol=1e-12)
            np.testing.assert_allclose(half, expected["std"].to_numpy(), rtol=1e-9)  # ddof=1, as pandas
        # the rows really differ, so a line drawn for the wrong row would fail
        assert not np.allclose(lines["objective=hybrid"][1], lines["objective=labelled"][1])


def test_sweep_learning_curves_one_line_per_objective_at_the_mean_over_seeds(sweep, drawn):
    write_summary(sweep)
    assert (sweep / "figures" / "learning_curves_compared.png").read_bytes()[:8] == PNG
    fig = drawn["learning_curves_compared"]
    frames = [pd.read_csv(run / "curves.csv").assign(objective=keys["objective"]) for keys, run in completed(sweep)]
    curves = pd.concat(frames)
    clean = curves[(curves.split == "test") & (curves.noise_std == 0)]
    ref = clean.groupby(["objective", "parameter", "step"]).mean_rel_dev.mean()

    assert len(fig.axes) == len(PARAMS)
    assert [ax.get_title() for ax in fig.axes] == PARAMS
    assert "test split" in fig.get_suptitle() and "noise 0" in fig.get_suptitle() and "over seeds" in fig.get_suptitle()
    assert sorted(legend_texts(fig.axes[0])) == sorted(f"objective={o}" for o in OBJECTIVES)
    for ax, param in zip(fig.axes, PARAMS):
        assert ax.get_xlabel() == "step" and "relative deviation" in ax.get_ylabel() and ax.get_yscale() == "log"
        assert len(ax.lines) == len(OBJECTIVES)
        for line in ax.lines:
            expected = ref.loc[(line.get_label().removeprefix("objective="), param)]
            np.testing.assert_allclose(line.get_xdata(), expected.index.to_numpy())
            np.testing.assert_allclose(line.get_ydata(), expected.to_numpy(), rtol=1e-12)


LEVELS, KS, N_REC = [0.0, 0.01, 0.1], [1, 4], 30


def fake_predictions(rng) -> pd.DataFrame:
    """predictions.csv as training.evaluation writes it: train and val at noise 0, test at every level and K
    (the same recordings at every K); the train rows are far off, so a figure of the test split that drew them
    would fail."""
    frames, truth = [], {split: rng.uniform(2.0, 12.0, size=(N_REC, 2)) for split in ("train", "val", "test")}
    evals = [("train", 0.0, 1), ("val", 0.0, 1)] + [("test", s, k) for s in LEVELS for k in KS]
    for split, std, k in evals:
        true = truth[split]
        pred = true * (1 + rng.normal(0.0, 0.5 if split == "train" else 0.03 * (1 + 10 * std) / k, size=true.shape))
        frames.append(
            pd.DataFrame(
                {
                    "split": split,
                    "noise_std": std,
                    "windows": k,
                    "recording": np.arange(N_REC),
                    "p1_true": true[:, 0],
                    "p1_pred": pred[:, 0],
                    "p2_true": true[:, 1],
                    "p2_pred": pred[:, 1],
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def test_run_figures_show_the_test_predictions_and_the_learning_curves(tmp_path, drawn):
    run = make_run(tmp_path / "run", ["seed=0"], 0)
    fake_predictions(np.random.default_rng(7)).to_csv(run / "predictions.csv", index=False)
    preds = pd.read_csv(run / "predictions.csv")  # the numbers as the figure reads them
    write_run_figures(run)
    for name in ("test_predictions", "learning_curves"):
        assert (run / "figures" / f"{name}.png").read_bytes()[:8] == PNG

    # test predictions: per noise level a row, per parameter the predictions and the histogram of deviations
    fig = drawn["test_predictions"]
    assert "test split" in fig.get_suptitle()
    axes = np.array(fig.axes).reshape(len(LEVELS), 2 * len(PARAMS))
    for ax in axes[-1, 0::2]:
        assert "test recording" in ax.get_xlabel()
    for row, std in enumerate(LEVELS):
        for j, param in enumerate(PARAMS):
            curve, hist = axes[row, 2 * j], axes[row, 2 * j + 1]
            assert f"noise std {std:g}" in curve.get_title() and param in curve.get_title()
            assert curve.get_ylabel() == param
            assert "relative deviation" in hist.get_title() and param in hist.get_title()
            assert len(curve.lines) == len(KS) + 1  # one line per K and the true values
            by_k = {int(re.match(r"K = (\d+):", ln.get_label()).group(1)): ln for ln in curve.lines[:-1]}
            assert sorted(by_k) == KS
            bars = list(hist.containers)
            assert len(bars) == len(KS)
            for k, bar, legend in zip(KS, bars, legend_texts(hist)):
                sub = preds[(preds.split == "test") & (preds.noise_std == std) & (preds.windows == k)]
                ordered = sub.sort_values(f"{param}_true")
                np.testing.assert_array_equal(by_k[k].get_ydata(), ordered[f"{param}_pred"].to_numpy())
                np.testing.assert_array_equal(curve.lines[-1].get_ydata(), ordered[f"{param}_true"].to_numpy())
                dev = ((sub[f"{param}_true"] - sub[f"{param}_pred"]).abs() / sub[f"{param}_true"]).to_numpy()
                counts, edges = np.histogram(dev, bins=40)
                np.testing.assert_array_equal([p.get_height() for p in bar], counts)
                np.testing.assert_allclose([p.get_x() for p in bar], edges[:-1], rtol=1e-12)
                # the legend gives the mean deviation in percent, to 2 decimals
                for text in (legend, by_k[k].get_label()):
                    shown = float(re.fullmatch(rf"K = {k}: mean ([\d.]+)%", text).group(1))
                    assert abs(shown - 100 * dev.mean()) <= 0.005 + 1e-9

    # learning curves: one line per split and noise level, the run's numbers
    fig = drawn["learning_curves"]
    curves = pd.read_csv(run / "curves.csv")
    groups = curves.groupby(["split", "noise_std"])
    assert len(fig.axes) == len(PARAMS) and [ax.get_title() for ax in fig.axes] == PARAMS
    assert sorted(legend_texts(fig.axes[0])) == sorted(f"{s}, noise {n:g}" for s, n in groups.groups)
    for ax, param in zip(fig.axes, PARAMS):
        assert ax.get_xlabel() == "step" and "relative deviation" in ax.get_ylabel()
        assert len(ax.lines) == groups.ngroups == 1 + len(NOISES)  # train at noise 0, test at every level
        for line in ax.lines:
            split, noise = line.get_label().split(", noise ")
            expected = curves[
                (curves.split == split) & np.isclose(curves.noise_std, float(noise)) & (curves.parameter == param)
            ].sort_values("step")
            np.testing.assert_array_equal(line.get_xdata(), expected.step.to_numpy())
            np.testing.assert_array_equal(line.get_ydata(), expected.mean_rel_dev.to_numpy())


def test_tuning_figure_one_line_per_objective_and_tuning_at_the_chosen_k(tmp_path, drawn):
    rng = np.random.default_rng(3)
    values, job = {}, 0  # (objective, tuning, seed, noise, K, parameter) -> mean_rel_dev
    for objective in OBJECTIVES:
        for tuning in ("default", "tuned"):
            for seed in (0, 1, 2):
                mine = {("test", n, k, p): rng.uniform(0.01, 0.4) for n in LEVELS for k in KS for p in PARAMS}
                values.update({(objective, tuning, seed, n, k, p): v for (_, n, k, p), v in mine.items()})
                make_run(
                    tmp_path / "sweep" / str(job),
                    [f"objective={objective}", f"tuning={tuning}", f"seed={seed}"],
                    seed,
                    results=known_results(mine),
                )
                job += 1
    _, df = load_runs(tmp_path / "sweep")
    tuning_figure(summary_table(df), tmp_path / "tuning.png", k=4)
    assert (tmp_path / "tuning.png").read_bytes()[:8] == PNG
    fig = drawn["tuning"]
    ref = pd.Series(values).rename_axis(["objective", "tuning", "seed", "noise", "K", "parameter"])
    ref = ref.groupby(["objective", "tuning", "K", "parameter", "noise"]).agg(["mean", "std"])

    assert "K = 4" in fig.get_suptitle() and "default" in fig.get_suptitle()  # it says what dashed means
    assert len(fig.axes) == len(PARAMS) and [ax.get_title() for ax in fig.axes] == PARAMS
    rows = [f"{o}, {t}" for o in OBJECTIVES for t in ("default", "tuned")]
    assert sorted(legend_texts(fig.axes[0])) == sorted(rows)
    for ax, param in zip(fig.axes, PARAMS):
        assert "noise" in ax.get_xlabel() and "relative deviation" in ax.get_ylabel()
        lines = errorbars(ax)
        assert sorted(lines) == sorted(rows)  # one line per row of the table at K = 4
        for label, (x, y, half) in lines.items():
            objective, tuning = label.split(", ")
            np.testing.assert_allclose(x, LEVELS)
            np.testing.assert_allclose(y, ref.loc[(objective, tuning, 4, param), "mean"].to_numpy(), rtol=1e-12)
            np.testing.assert_allclose(half, ref.loc[(objective, tuning, 4, param), "std"].to_numpy(), rtol=1e-9)
            assert not np.allclose(y, ref.loc[(objective, tuning, 1, param), "mean"].to_numpy())  # not K = 1
        style = {c.get_label(): c.lines[0] for c in ax.containers}
        for objective in OBJECTIVES:  # one colour per objective, dashed with its default values
            default, tuned = style[f"{objective}, default"], style[f"{objective}, tuned"]
            assert default.get_linestyle() == "--" and tuned.get_linestyle() == "-"
            assert to_rgba(default.get_color()) == to_rgba(tuned.get_color())
        assert to_rgba(style["labelled, tuned"].get_color()) != to_rgba(style["hybrid, tuned"].get_color())
