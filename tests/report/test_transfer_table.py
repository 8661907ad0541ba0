"""experiment=transfer's table: nested sub-runs found, rows (scenario, row), marks within a scenario, bar figure."""

from evaluation_fakes import known_results, make_run

from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import compare_marks, summary_table
from hybrid_sysid.report.sweep_figures import transfer_figure

ROWS = ["1 labelled, paper's car", "2 + hybrid adaptation"]


def make_transfer_sweep(root):
    # one job directory per seed, the sub-runs nested in it as hybrid_sysid.transfer lays them out
    for seed in (0, 1):
        for scenario, values in (("seat_shift", (0.19, 0.02)), ("body_shift", (0.015, 0.011))):
            for row, value in zip(ROWS, values):
                name = "source" if row.startswith("1") else "adapted"
                make_run(root / str(seed) / scenario / name,
                         ["experiment=transfer", f"scenario={scenario}", f"row={row}", f"seed={seed}"], seed,
                         results=known_results({("test", 0.0, p): value + 0.001 * seed for p in ("p1", "p2")}))
    return root


def test_rows_are_scenario_and_row_compared_within_a_scenario(tmp_path):
    root, df = load_runs(make_transfer_sweep(tmp_path / "sweep"))
    table = summary_table(df)
    assert list(table.index.names) == ["scenario", "row"]
    assert table.loc[("seat_shift", ROWS[0]), (0.0, "p1", "mean")] == 0.1905
    marks = compare_marks(table)  # the compared level defaults to "row"
    assert marks.loc[("seat_shift", ROWS[1]), (0.0, "p1")] == "best"
    assert marks.loc[("seat_shift", ROWS[0]), (0.0, "p1")] == "worse"
    assert marks.loc[("body_shift", ROWS[1]), (0.0, "p1")] == "best"  # its own group, not the seat's


def test_the_bar_figure_is_drawn(tmp_path):
    _, table = write_summary(make_transfer_sweep(tmp_path / "sweep"), figures=False)
    transfer_figure(table, tmp_path / "bars.png")
    assert (tmp_path / "bars.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
