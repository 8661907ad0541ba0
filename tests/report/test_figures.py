"""What a reader sees in each figure the project draws, asserted on the matplotlib Figure (the ``drawn`` fixture
catches it as it is saved): panels, axis labels (percent, as the tables; the noise axis says its levels are evenly
spaced), titles, the figure's one legend, one line per row of the data given, colour and line style per objective
and K, and the plotted numbers against a reference computed here from the fake records with pandas and numpy, and
against the percentages the markdown table prints. The transfer bar figure is tested with its table in
test_transfer_table.py; that the PNG files are real plots, in test_report_cli.py."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import to_rgba

from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.run_figures import write_run_figures
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.sweep_figures import DODGE
from hybrid_sysid.report.tables import summary_table
from hybrid_sysid.report.tuning import tuning_figure

from helpers.evaluation_fakes import NOISES, OBJECTIVES, PARAMS, known_results, make_run, parse_markdown, plain

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


def legend_texts(fig) -> list[str]:
    """The texts of the figure's one legend; no panel has a legend of its own."""
    assert len(fig.legends) == 1 and all(ax.get_legend() is None for ax in fig.axes)
    return [t.get_text() for t in fig.legends[0].get_texts()]


def assert_noise_axis(ax, levels) -> None:
    """The noise levels as evenly spaced categories, and the label says so; y in percent, log scale."""
    assert "noise std" in ax.get_xlabel() and "evenly spaced" in ax.get_xlabel() and "not to scale" in ax.get_xlabel()
    assert [t.get_text() for t in ax.get_xticklabels()] == [f"{n:g}" for n in levels]
    np.testing.assert_allclose(ax.get_xticks(), np.arange(len(levels)))
    assert "relative deviation" in ax.get_ylabel() and ax.get_ylabel().endswith("[%]")
    assert ax.get_yscale() == "log"


def positions(x, levels) -> np.ndarray:
    """The noise levels a line's x positions stand for (each level's position, the line spread by at most DODGE / 2
    around it)."""
    index = np.round(x).astype(int)
    assert np.all(np.abs(x - index) <= DODGE / 2 + 1e-12)
    return np.asarray(levels)[index]


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
    assert sorted(legend_texts(fig)) == sorted(f"objective={o}" for o in OBJECTIVES)  # names the rows
    for ax, param in zip(fig.axes, PARAMS):
        assert_noise_axis(ax, NOISES)
        lines = errorbars(ax)
        assert len(lines) == len(OBJECTIVES)  # one line per table row
        for objective in OBJECTIVES:
            x, y, half = lines[f"objective={objective}"]
            expected = ref.loc[(objective, param)]
            np.testing.assert_allclose(positions(x, NOISES), NOISES)
            np.testing.assert_allclose(y, 100 * expected["mean"].to_numpy(), rtol=1e-12)  # percent
            np.testing.assert_allclose(half, 100 * expected["std"].to_numpy(), rtol=1e-9)  # ddof=1, as pandas
        # the rows really differ, so a line drawn for the wrong row would fail
        assert not np.allclose(lines["objective=hybrid"][1], lines["objective=labelled"][1])
        # one colour per objective, solid (there is no K level)
        styles = {c.get_label(): c.lines[0] for c in ax.containers}
        assert all(line.get_linestyle() == "-" for line in styles.values())
        assert len({to_rgba(line.get_color()) for line in styles.values()}) == len(OBJECTIVES)


KS_SWEPT = [1, 8]


def k_sweep(root) -> Path:
    """3 objectives x 3 seeds, each evaluated at K = 1 and K = 8 at every noise level; K = 8 lower."""
    rng, job = np.random.default_rng(11), 0
    for objective in ("labelled", "hybrid", "combined"):
        for seed in range(3):
            values = {
                ("test", n, k, p): rng.uniform(0.02, 0.3) / (2 if k == 8 else 1)
                for n in NOISES
                for k in KS_SWEPT
                for p in PARAMS
            }
            make_run(root / str(job), [f"objective={objective}", f"seed={seed}"], seed, results=known_results(values))
            job += 1
    return root


def test_robustness_figure_one_hue_per_objective_k1_solid_k8_dashed_in_the_tables_percent(tmp_path, drawn):
    write_summary(k_sweep(tmp_path / "sweep"))
    fig = drawn["robustness"]
    _, df = load_runs(tmp_path / "sweep")
    table = summary_table(df)
    assert list(table.index.names) == ["objective", "K"]
    # the percentages the markdown table prints, read back from it: the figure shows the same numbers
    shown = {
        (r["objective"], int(r["K"])): {
            (n, p): [float(v) for v in plain(r[f"noise {n:g} {p} [%]"]).split(" ± ")] for n in NOISES for p in PARAMS
        }
        for r in parse_markdown(to_markdown(table))
    }
    rows = [f"objective={o}, K={k}" for o in ("combined", "hybrid", "labelled") for k in KS_SWEPT]
    assert legend_texts(fig) == rows  # table order: the K = 1 and K = 8 rows of an objective side by side
    assert "solid: K = 1" in fig.get_suptitle() and "dashed: K = 8" in fig.get_suptitle()
    for ax, param in zip(fig.axes, PARAMS):
        assert_noise_axis(ax, NOISES)
        lines = errorbars(ax)
        assert sorted(lines) == sorted(rows)
        styles = {c.get_label(): c.lines[0] for c in ax.containers}
        for objective in ("combined", "hybrid", "labelled"):
            own = [label for label in lines if label.startswith(f"objective={objective},")]
            assert len(own) == len(KS_SWEPT)  # one line per K
            k1, k8 = styles[f"objective={objective}, K=1"], styles[f"objective={objective}, K=8"]
            assert k1.get_linestyle() == "-" and k8.get_linestyle() == "--"
            assert to_rgba(k1.get_color()) == to_rgba(k8.get_color())  # one hue per objective
            for k in KS_SWEPT:
                x, y, half = lines[f"objective={objective}, K={k}"]
                np.testing.assert_allclose(positions(x, NOISES), NOISES)
                mean = [shown[(objective, k)][(n, param)][0] for n in NOISES]
                std = [shown[(objective, k)][(n, param)][1] for n in NOISES]
                np.testing.assert_allclose(y, mean, atol=0.005 + 1e-9)  # the table's 2 decimals
                np.testing.assert_allclose(half, std, atol=0.005 + 1e-9)
                np.testing.assert_allclose(y, 100 * table.loc[(objective, k), [(n, param, "mean") for n in NOISES]])
        hues = {to_rgba(styles[f"objective={o}, K=1"].get_color()) for o in ("combined", "hybrid", "labelled")}
        assert len(hues) == 3


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
    assert sorted(legend_texts(fig)) == sorted(f"objective={o}" for o in OBJECTIVES)
    for ax, param in zip(fig.axes, PARAMS):
        assert ax.get_xlabel() == "step" and ax.get_yscale() == "log"
        assert "relative deviation" in ax.get_ylabel() and ax.get_ylabel().endswith("[%]")
        assert len(ax.lines) == len(OBJECTIVES)
        for line in ax.lines:
            expected = ref.loc[(line.get_label().removeprefix("objective="), param)]
            np.testing.assert_allclose(line.get_xdata(), expected.index.to_numpy())
            np.testing.assert_allclose(line.get_ydata(), 100 * expected.to_numpy(), rtol=1e-12)  # percent


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
    # one legend for the figure: the colour of each K (its dots and bars), and the true values
    assert legend_texts(fig) == [f"K = {k}" for k in KS] + ["true value"]
    axes = np.array(fig.axes).reshape(len(LEVELS), 2 * len(PARAMS))
    for ax in axes[-1, 0::2]:
        assert "test recording" in ax.get_xlabel()
    for ax in axes[-1, 1::2]:
        assert "relative deviation" in ax.get_xlabel() and ax.get_xlabel().endswith("[%]")
    for row, std in enumerate(LEVELS):
        for j, param in enumerate(PARAMS):
            curve, hist = axes[row, 2 * j], axes[row, 2 * j + 1]
            assert f"noise std {std:g}" in curve.get_title() and param in curve.get_title()
            assert curve.get_ylabel() == param
            assert "relative deviation" in hist.get_title() and param in hist.get_title()
            assert len(curve.lines) == len(KS) + 1  # one line per K and the true values
            by_k = {int(re.fullmatch(r"K = (\d+)", ln.get_label()).group(1)): ln for ln in curve.lines[:-1]}
            assert sorted(by_k) == KS and curve.lines[-1].get_label() == "true value"
            colours = {k: to_rgba(ln.get_color()) for k, ln in by_k.items()}
            legend = dict(zip(legend_texts(fig), fig.legends[0].legend_handles))
            bars = list(hist.containers)
            assert len(bars) == len(KS)
            at = preds[(preds.split == "test") & (preds.noise_std == std)]
            devs = {}
            for k in KS:
                sub = at[at.windows == k]
                devs[k] = 100 * ((sub[f"{param}_true"] - sub[f"{param}_pred"]).abs() / sub[f"{param}_true"]).to_numpy()
            edges = np.histogram_bin_edges(np.concatenate([devs[k] for k in KS]), bins=40)  # shared by the Ks
            (text,) = hist.texts
            for k, bar in zip(KS, bars):
                sub = at[at.windows == k]
                ordered = sub.sort_values(f"{param}_true")
                np.testing.assert_array_equal(by_k[k].get_ydata(), ordered[f"{param}_pred"].to_numpy())
                np.testing.assert_array_equal(curve.lines[-1].get_ydata(), ordered[f"{param}_true"].to_numpy())
                counts, _ = np.histogram(devs[k], bins=edges)
                np.testing.assert_array_equal([p.get_height() for p in bar], counts)
                np.testing.assert_allclose([p.get_x() for p in bar], edges[:-1], rtol=1e-12)  # percent
                # dots, bars and the legend entry share the K's colour
                assert to_rgba(bar[0].get_facecolor())[:3] == colours[k][:3]
                assert to_rgba(legend[f"K = {k}"].get_facecolor())[:3] == colours[k][:3]
                # the panel gives the mean deviation in percent, to 2 decimals
                shown = float(re.search(rf"K = {k}: mean ([\d.]+)%", text.get_text()).group(1))
                assert abs(shown - devs[k].mean()) <= 0.005 + 1e-9

    # learning curves: one line per split and noise level, the run's numbers
    fig = drawn["learning_curves"]
    curves = pd.read_csv(run / "curves.csv")
    groups = curves.groupby(["split", "noise_std"])
    assert len(fig.axes) == len(PARAMS) and [ax.get_title() for ax in fig.axes] == PARAMS
    assert sorted(legend_texts(fig)) == sorted(f"{s}, noise {n:g}" for s, n in groups.groups)
    for ax, param in zip(fig.axes, PARAMS):
        assert ax.get_xlabel() == "step" and "relative deviation" in ax.get_ylabel() and "[%]" in ax.get_ylabel()
        assert len(ax.lines) == groups.ngroups == 1 + len(NOISES)  # train at noise 0, test at every level
        for line in ax.lines:
            split, noise = line.get_label().split(", noise ")
            expected = curves[
                (curves.split == split) & np.isclose(curves.noise_std, float(noise)) & (curves.parameter == param)
            ].sort_values("step")
            np.testing.assert_array_equal(line.get_xdata(), expected.step.to_numpy())
            np.testing.assert_allclose(line.get_ydata(), 100 * expected.mean_rel_dev.to_numpy(), rtol=1e-12)


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
    assert sorted(legend_texts(fig)) == sorted(rows)
    for ax, param in zip(fig.axes, PARAMS):
        assert_noise_axis(ax, LEVELS)
        lines = errorbars(ax)
        assert sorted(lines) == sorted(rows)  # one line per row of the table at K = 4
        for label, (x, y, half) in lines.items():
            objective, tuning = label.split(", ")
            expected = ref.loc[(objective, tuning, 4, param)]
            np.testing.assert_allclose(positions(x, LEVELS), LEVELS)
            np.testing.assert_allclose(y, 100 * expected["mean"].to_numpy(), rtol=1e-12)  # percent
            np.testing.assert_allclose(half, 100 * expected["std"].to_numpy(), rtol=1e-9)
            assert not np.allclose(y, 100 * ref.loc[(objective, tuning, 1, param), "mean"].to_numpy())  # not K = 1
        style = {c.get_label(): c.lines[0] for c in ax.containers}
        for objective in OBJECTIVES:  # one colour per objective, dashed with its default values
            default, tuned = style[f"{objective}, default"], style[f"{objective}, tuned"]
            assert default.get_linestyle() == "--" and tuned.get_linestyle() == "-"
            assert to_rgba(default.get_color()) == to_rgba(tuned.get_color())
        assert to_rgba(style["labelled, tuned"].get_color()) != to_rgba(style["hybrid, tuned"].get_color())


def test_a_table_of_more_rows_than_one_figure_shows_apart_gets_no_robustness_figure(tmp_path, drawn):
    from hybrid_sysid.report.results_page import write_results
    from hybrid_sysid.report.sweep_figures import MAX_ROWS

    # MAX_ROWS // 2 + 1 values of a swept key x K = 1 and 8: two rows more than MAX_ROWS
    rng, sweep = np.random.default_rng(5), tmp_path / "wide"
    for i in range(MAX_ROWS // 2 + 1):
        values = {("test", n, k, p): rng.uniform(0.02, 0.3) for n in NOISES for k in KS_SWEPT for p in PARAMS}
        make_run(sweep / str(i), [f"model.optim.lr={0.001 * (i + 1):g}", "seed=0"], 0, results=known_results(values))
    write_summary(sweep)
    assert "robustness" not in drawn and not (sweep / "figures" / "robustness.png").exists()
    assert (sweep / "summary.md").is_file()  # the table still is
    page, _, _ = write_results(tmp_path / "results.md", [sweep], command="the test's sweep")
    assert f"No robustness figure: {2 * (MAX_ROWS // 2 + 1)} rows" in page and "![robustness" not in page
