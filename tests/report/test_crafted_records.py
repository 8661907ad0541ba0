"""Records crafted by hand (a received sweep): a deviation that is text or negative makes its run unreadable, one
row listed under the table, never a value of the table nor a crash of the report."""

import json

import pandas as pd

from hybrid_sysid.cli.report import main

from helpers.evaluation_fakes import make_sweep


def test_deviations_that_are_text_or_negative_make_their_runs_unreadable_never_a_crash(tmp_path, capsys):
    sweep = make_sweep(tmp_path / "sweep", failed=False)
    jobs = sorted(p for p in sweep.iterdir() if (p / "metrics.json").is_file())
    for i, job in enumerate(jobs):  # every job: with none left readable the figures' log scale once crashed
        record = json.loads((job / "metrics.json").read_text())
        for row in record["results"]:
            row["mean_rel_dev"] = "NaN%" if i % 2 else -1.0
        (job / "metrics.json").write_text(json.dumps(record))
    assert main([str(sweep)]) == 1  # everything written, the runs unreadable
    assert set(pd.read_csv(sweep / "summary.csv").status) == {"unreadable"}
    failed = (sweep / "summary.md").read_text().split("## Failed jobs", 1)[1]
    assert failed.count("a relative deviation is a number >= 0") == len(jobs)
    assert "mean_rel_dev = 'NaN%'" in failed and "mean_rel_dev = -1.0" in failed


def test_a_cramer_rao_bound_that_is_no_number_in_range_is_left_out_of_the_bound_row(tmp_path):
    """A record whose bound columns were edited (negative, text, nan, 1e308, true) counts as one without a bound:
    the bound row is the other runs' (it read -12.50% and inf)."""
    from hybrid_sysid.report.collect import load_runs
    from hybrid_sysid.report.tables import bound_table

    sweep = make_sweep(tmp_path / "sweep", failed=False)
    jobs = sorted(p for p in sweep.iterdir() if (p / "metrics.json").is_file())
    hostile = [-1.0, "abc", float("nan"), 1e308, True]
    for i, job in enumerate(jobs):
        record = json.loads((job / "metrics.json").read_text())
        for j, row in enumerate(record["results"]):
            row["bound"] = hostile[j % len(hostile)] if i == 0 else 0.05
        (job / "metrics.json").write_text(json.dumps(record))
    _, df = load_runs(sweep)
    bound = bound_table(df)
    assert not bound.empty and ((bound - 0.05).abs() < 1e-12).all().all(), bound
