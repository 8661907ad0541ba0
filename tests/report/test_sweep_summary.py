"""The sweep summary against the run records it is built from. Spread over seeds: sample std, ddof=1."""

import csv
import json
import math

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.report.collect import collect, find_runs
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import summary_table

from helpers.evaluation_fakes import (
    FAILED_ERROR,
    NOISES,
    OBJECTIVES,
    PARAMS,
    SEEDS,
    make_run,
    make_sweep,
    parse_markdown,
    plain,
)

DDOF = 1


def test_find_runs_at_or_below_each_path_sorted_and_deduplicated(tmp_path):
    a, b = make_sweep(tmp_path / "a", failed=False), make_sweep(tmp_path / "b")
    single = make_run(tmp_path / "single", ["seed=0"], 0)
    (tmp_path / "b" / "5" / "notes").mkdir()  # an unrelated folder below a run is not a run
    found = find_runs([tmp_path, a, a / "0", single, str(b)])
    assert found == sorted({*(a / str(i) for i in range(4)), *(b / str(i) for i in range(6)), single})
    assert find_runs(single) == [single]
    assert find_runs(tmp_path / "a" / "0" / ".hydra") == []


def test_summary_csv_carries_every_record_number_exactly(sweep):
    write_summary(sweep, figures=False)
    with open(sweep / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    for job in range(4):
        rec = json.loads((sweep / str(job) / "metrics.json").read_text())
        mine = [r for r in rows if r["run"] == str(job)]
        assert len(mine) == len(rec["results"]) == 6 * len(PARAMS)
        for want in rec["results"]:
            [got] = [
                r
                for r in mine
                if r["split"] == want["split"]
                and float(r["noise_std"]) == want["noise_std"]
                and r["parameter"] == want["parameter"]
            ]
            assert float(got["mean_rel_dev"]) == want["mean_rel_dev"]  # exact: no rounding on the way
            assert float(got["std_rel_dev"]) == want["std_rel_dev"]
            assert int(got["n"]) == want["n"]
            assert (got["status"], int(got["seed"]), int(got["steps"]), float(got["train_seconds"])) == (
                "completed",
                rec["seed"],
                rec["steps"],
                rec["train_seconds"],
            )
            assert got["objective"] == rec["overrides"][0].split("=")[1] and got["noise"] == "ladder"
    assert "seed" in rows[0] and list(rows[0]).count("seed") == 1  # "seed=1" is not a second seed column


def test_failed_and_corrupt_jobs_are_one_row_each_never_a_crash(sweep):
    df = collect(sweep)
    failed, corrupt = df[df.run == "4"], df[df.run == "5"]
    assert len(failed) == 1 and len(corrupt) == 1
    f, c = failed.iloc[0], corrupt.iloc[0]
    assert (f.status, f.error, f.seed, f.objective) == ("failed", FAILED_ERROR, 2, "hybrid")
    assert c.status == "unreadable" and "JSONDecodeError" in c.error
    assert (c.objective, c.seed) == ("labelled", 2)  # recovered from .hydra/overrides.yaml
    for row in (f, c):
        assert all(pd.isna(row[k]) for k in ("split", "noise_std", "parameter", "mean_rel_dev", "std_rel_dev", "n"))


def test_corrupt_run_without_hydra_dir_and_union_of_override_keys(tmp_path):
    make_run(tmp_path / "r0", ["objective=labelled", "seed=0"], 0)
    make_run(tmp_path / "r1", ["objective=hybrid", "seed=0", "road=C"], 0)
    make_run(tmp_path / "r2", [], 0, corrupt=True, hydra=False)
    make_run(tmp_path / "r3", ["seed=0"], 0, corrupt=False, hydra=False, status="completed")
    df = collect(tmp_path)
    runs = df.drop_duplicates("run").set_index("run")
    assert runs.loc["r0", "road"] == "" and runs.loc["r1", "road"] == "C" and runs.loc["r3", "objective"] == ""
    assert runs.loc["r2", "status"] == "unreadable" and pd.isna(runs.loc["r2", "seed"])
    table = summary_table(df)
    assert list(table.index.names) == ["objective", "road"]
    assert table.loc[("", ""), ("n_failed", "", "")] == 1  # r2: configuration unknown
    assert table.loc[("", ""), ("n_seeds", "", "")] == 1  # r3: ran with the defaults


def _expected(sweep, objective, noise, param, metric="mean_rel_dev"):
    """The metric of each completed seed, read from the records directly."""
    values = []
    for job in range(4):
        rec = json.loads((sweep / str(job) / "metrics.json").read_text())
        if f"objective={objective}" in rec["overrides"]:
            values += [
                r[metric]
                for r in rec["results"]
                if (r["split"], r["noise_std"], r["parameter"]) == ("test", noise, param)
            ]
    assert len(values) == len(SEEDS)
    return np.array(values)


@pytest.mark.parametrize("metric", ["mean_rel_dev", "std_rel_dev"])
def test_table_and_markdown_cells_are_mean_and_sample_std_over_seeds(sweep, metric):
    df = collect(sweep)
    table = summary_table(df, metric=metric)
    assert list(table.index) == sorted(OBJECTIVES)  # the only swept key other than seed
    rows = {r["objective"]: r for r in parse_markdown(to_markdown(table))}
    for objective in OBJECTIVES:
        for noise in NOISES:
            for param in PARAMS:
                v = _expected(sweep, objective, noise, param, metric)
                mean, std = np.mean(v), np.std(v, ddof=DDOF)
                assert table.loc[objective, (noise, param, "mean")] == pytest.approx(mean, rel=1e-12)
                assert table.loc[objective, (noise, param, "std")] == pytest.approx(std, rel=1e-12)
                assert plain(rows[objective][f"noise {noise:g} {param} [%]"]) == f"{100 * mean:.2f} ± {100 * std:.2f}"
        assert rows[objective]["seeds"] == "2" and rows[objective]["failed"] == "1"  # 4: failed, 5: corrupt


def test_single_seed_has_no_spread_and_one_all_row(tmp_path):
    make_run(tmp_path / "run", ["objective=hybrid", "seed=3"], 3)
    df = collect(tmp_path / "run")
    assert set(df.run) == {"run"} and (df.seed == 3).all()
    table = summary_table(df)
    assert list(table.index) == ["all"]
    assert table[("n_seeds", "", "")].tolist() == [1] and math.isnan(table.iloc[0][(0.01, "p1", "std")])
    [row] = parse_markdown(to_markdown(table))
    v = df[(df.split == "test") & (df.noise_std == 0.01) & (df.parameter == "p1")].mean_rel_dev.item()
    assert row["all"] == "all" and row["noise 0.01 p1 [%]"] == f"{100 * v:.2f}"


def test_summary_md_lists_failed_jobs_and_files_are_written_atomically(sweep):
    df, table = write_summary(sweep, figures=False)
    md = (sweep / "summary.md").read_text(encoding="utf-8")
    assert md.startswith("# ")
    assert to_markdown(table) in md
    assert "- `4` (objective=hybrid, seed=2): failed: RuntimeError: loss is nan at step 120 while training" in md
    assert "- `5` (objective=labelled, seed=2): unreadable: metrics.json is damaged: JSONDecodeError" in md
    assert not list(sweep.glob(".*.tmp"))
    assert len(pd.read_csv(sweep / "summary.csv")) == len(df)


def test_bad_metric_and_empty_paths_raise_valueerror(sweep, tmp_path):
    with pytest.raises(ValueError, match="metric = 'rmse' is not allowed: one of"):
        summary_table(collect(sweep), metric="rmse")
    with pytest.raises(ValueError, match="is not allowed: directories with runs"):
        write_summary(tmp_path)


def test_merged_sweeps_fill_a_key_a_run_did_not_override_from_its_saved_config(tmp_path):
    # sweep a varied data.measurement; sweep b left it at its default (consistent) and varied only objective.
    # Merged, b's runs belong in the "consistent" rows, read from their .hydra/config.yaml, not a blank row.
    for seed in (0, 1):
        make_run(
            tmp_path / "a" / str(seed),
            ["objective=hybrid", "data.measurement=paper", f"seed={seed}"],
            seed,
            config={"data": {"measurement": "paper"}},
        )
        make_run(
            tmp_path / "b" / str(seed),
            ["objective=hybrid", f"seed={seed}"],
            seed,
            config={"data": {"measurement": "consistent"}},
        )
    make_run(tmp_path / "c" / "0", ["objective=labelled", "seed=0"], 0, hydra=False)  # no .hydra/: stays blank
    df = collect([tmp_path / "a", tmp_path / "b", tmp_path / "c"])
    labels = df.groupby("run")["data.measurement"].first().to_dict()
    assert labels == {"a/0": "paper", "a/1": "paper", "b/0": "consistent", "b/1": "consistent", "c/0": ""}
    objective = df.groupby("run")["objective"].first().to_dict()
    assert objective["c/0"] == "labelled" and objective["b/1"] == "hybrid"
