"""experiment=transfer's and experiment=field's table: nested sub-runs found, rows (scenario, row) in reading
order, marks within a scenario, bar figure."""

import numpy as np
import pytest
from matplotlib.container import BarContainer

from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.summary import tested_table as with_extras
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import compare_marks
from hybrid_sysid.report.transfer_figure import transfer_figure

from helpers.evaluation_fakes import PARAMS, known_results, make_run

ROWS = ["1 labelled, paper's car", "2 + hybrid adaptation"]
VALUES = {"seat_shift": (0.19, 0.02), "body_shift": (0.015, 0.011)}  # per row; seed s adds 0.001 * s
SEEDS = (0, 1)


def make_transfer_sweep(root):
    # one job directory per seed, the sub-runs nested in it as hybrid_sysid.experiments.transfer lays them out
    for seed in SEEDS:
        for scenario, values in VALUES.items():
            for row, value in zip(ROWS, values):
                name = "source" if row.startswith("1") else "adapted"
                make_run(
                    root / str(seed) / scenario / name,
                    ["experiment=transfer", f"scenario={scenario}", f"row={row}", f"seed={seed}"],
                    seed,
                    results=known_results({("test", 0.0, p): value + 0.001 * seed for p in ("p1", "p2")}),
                )
    return root


def test_rows_are_scenario_and_row_compared_within_a_scenario(tmp_path):
    root, df = load_runs(make_transfer_sweep(tmp_path / "sweep"))
    table = with_extras(df, root)  # with what experiment=transfer adds: its marks compare the rows
    assert list(table.index.names) == ["scenario", "row"]
    assert table.loc[("seat_shift", ROWS[0]), (0.0, "p1", "mean")] == 0.1905
    marks = compare_marks(table)  # the compared level defaults to "row"
    assert marks.loc[("seat_shift", ROWS[1]), (0.0, "p1")] == "best"
    assert marks.loc[("seat_shift", ROWS[0]), (0.0, "p1")] == "worse"
    assert marks.loc[("body_shift", ROWS[1]), (0.0, "p1")] == "best"  # its own group, not the seat's


def test_the_bar_figure_is_drawn(tmp_path, drawn):
    _, table = write_summary(make_transfer_sweep(tmp_path / "sweep"), figures=False)
    transfer_figure(table, tmp_path / "bars.png")
    assert (tmp_path / "bars.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # what a reader sees: a panel per scenario, a group of bars per row, a bar per parameter in percent
    fig = drawn["bars"]
    assert "noise std 0" in fig.get_suptitle() and "K = 1" in fig.get_suptitle()
    assert sorted(ax.get_title() for ax in fig.axes) == sorted(VALUES)
    assert "relative deviation" in fig.axes[0].get_ylabel() and "%" in fig.axes[0].get_ylabel()
    # one legend for the figure, none in a panel
    assert len(fig.legends) == 1 and all(ax.get_legend() is None for ax in fig.axes)
    assert [t.get_text() for t in fig.legends[0].get_texts()] == PARAMS
    for ax in fig.axes:
        assert [t.get_text() for t in ax.get_xticklabels()] == ROWS  # the groups named by their row
        per_param = [c for c in ax.containers if isinstance(c, BarContainer)]
        assert len(per_param) == len(PARAMS) and all(len(c) == len(ROWS) for c in per_param)
        # percent, the mean and the sample std (ddof=1) over seeds, computed here from the values written
        runs = 100 * (np.array(VALUES[ax.get_title()])[:, None] + 0.001 * np.array(SEEDS)[None, :])
        for bars in per_param:
            np.testing.assert_allclose([b.get_height() for b in bars], runs.mean(axis=1), rtol=1e-9)
            segments = bars.errorbar.lines[2][0].get_segments()
            np.testing.assert_allclose([(s[1, 1] - s[0, 1]) / 2 for s in segments], runs.std(axis=1, ddof=1), rtol=1e-6)
        # p1 left of p2 in each row's group
        centres = [[b.get_x() + b.get_width() / 2 for b in bars] for bars in per_param]
        assert all(a < b < a + 1 for a, b in zip(*centres))


# experiment=field's rows (hybrid_sysid.experiments.transfer), written here in another order than they read
FIELD_ROWS = {
    "5 ls_bandpass (no network)": ("baseline_ls_bandpass", 0.004),
    "2 + label_free adaptation": ("adapted_label_free", 0.03),
    "1 labelled, paper's car": ("source", 0.2),
    "3 label_free from scratch": ("scratch_label_free", 0.05),
    "2 + hybrid_bandpass adaptation": ("adapted_hybrid_bandpass", 0.06),
    "4 labelled oracle": ("oracle", 0.01),
    "2 + hybrid adaptation": ("adapted", 0.1),
}


def make_field_sweep(root):
    for seed in SEEDS:
        make_run(
            root / str(seed) / "source",
            ["experiment=field", "scenario=paper", "row=1 labelled, paper's car", f"seed={seed}"],
            seed,
            results=known_results({("test", 0.0, p): 0.02 + 0.001 * seed for p in ("p1", "p2")}),
        )
        for row, (name, value) in FIELD_ROWS.items():
            make_run(
                root / str(seed) / "field" / name,
                ["experiment=field", "scenario=field", f"row={row}", f"seed={seed}"],
                seed,
                results=known_results({("test", 0.0, p): value + 0.001 * seed for p in ("p1", "p2")}),
            )
    return root


def test_every_row_of_a_field_sweep_in_reading_order_and_drawn(tmp_path, drawn):
    _, table = write_summary(make_field_sweep(tmp_path / "sweep"), figures=False)
    reading = [
        "1 labelled, paper's car",
        "2 + hybrid adaptation",
        "2 + hybrid_bandpass adaptation",
        "2 + label_free adaptation",
        "3 label_free from scratch",
        "4 labelled oracle",
        "5 ls_bandpass (no network)",
    ]
    assert list(table.loc["field"].index) == reading
    assert compare_marks(table).loc[("field", "5 ls_bandpass (no network)"), (0.0, "p1")] == "best"
    transfer_figure(table, tmp_path / "bars.png")
    fig = drawn["bars"]
    by_title = {ax.get_title(): ax for ax in fig.axes}
    assert [t.get_text() for t in by_title["field"].get_xticklabels()] == reading
    bars = [c for c in by_title["field"].containers if isinstance(c, BarContainer)]
    np.testing.assert_allclose(
        [b.get_height() for b in bars[0]], [100 * (FIELD_ROWS[r][1] + 0.0005) for r in reading], rtol=1e-9
    )
    # a panel as wide as its rows (the one-row panel as three): every group of bars is equally wide on the page
    widths = {t: ax.get_position().width / (ax.get_xlim()[1] - ax.get_xlim()[0]) for t, ax in by_title.items()}
    assert by_title["paper"].get_xlim() == (-0.5, 2.5) and by_title["field"].get_xlim() == (-0.5, 6.5)
    assert widths["field"] == pytest.approx(widths["paper"], rel=0.02)
