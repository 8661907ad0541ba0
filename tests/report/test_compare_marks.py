"""Statistics of the comparison table against numbers computed by hand here (numpy): means and sample stds
over seeds, the best row per column, and whether a gap exceeds the combined seed spread, including gaps just
below and just above it; the windows (K) level; the LaTeX form."""

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.report.collect import collect
from hybrid_sysid.report.latex import to_latex
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import compare_marks, summary_table

from helpers.evaluation_fakes import known_results, make_run, parse_markdown, plain

EPS = 1e-6  # relative distance of a gap from the spread: far above rounding, far below any real difference
LAB = np.array([0.10, 0.12, 0.14])  # mean 0.12, sample std 0.02
SPREAD = 0.02 + 0.01  # LAB's std + the std of the +-0.01 offsets below
OFF = np.array([-0.01, 0.0, 0.01])  # sample std 0.01
# (objective -> seed values) per column; test split
COLUMNS = {
    (0.0, "p1"): {
        "labelled": LAB,
        "hybrid": 0.12 + SPREAD * (1 + EPS) + OFF,  # just above: worse
        "combined": 0.12 + SPREAD * (1 - EPS) + OFF,
    },  # just below: within
    (0.0, "p2"): {"labelled": LAB + 0.5, "hybrid": LAB * 0.5, "combined": LAB * 0.5 + 0.001},
    (0.01, "p1"): {"labelled": 0.27 + 3 * OFF, "hybrid": 0.16 + OFF, "combined": 0.2 + OFF},
    (0.01, "p2"): {"labelled": LAB, "hybrid": LAB, "combined": LAB + 1.0},  # a tie: the first row is best
}
OBJECTIVES = ["combined", "hybrid", "labelled"]  # table order: sorted


def _values(objective, seed, column_values=COLUMNS):
    return {("test", n, p): v[objective][seed] for (n, p), v in column_values.items()}


@pytest.fixture
def known(tmp_path):
    job = 0
    for objective in OBJECTIVES:
        for seed in range(3):
            vals = _values(objective, seed)
            vals[("train", 0.0, "p1")] = vals[("train", 0.0, "p2")] = 0.05
            make_run(
                tmp_path / "sw" / str(job),
                [f"objective={objective}", f"seed={seed}"],
                seed,
                results=known_results(vals),
            )
            job += 1
    return tmp_path / "sw"


def t_interval_by_hand(v) -> tuple[float, float]:
    """The 95% Student t interval of the mean: mean -+ t_(0.975, n-1) s / sqrt(n), t's quantile from scipy."""
    from scipy.stats import t

    half = t.ppf(0.975, len(v) - 1) * np.std(v, ddof=1) / np.sqrt(len(v))
    return np.mean(v) - half, np.mean(v) + half


def _by_hand(values: dict) -> dict:
    """For one column: {objective: mark} by the rule, computed with numpy from the seed values."""
    mean = {o: np.mean(v) for o, v in values.items()}
    std = {o: np.std(v, ddof=1) for o, v in values.items()}
    best = min(OBJECTIVES, key=lambda o: mean[o])  # table order breaks ties
    return {
        o: "best" if o == best else "worse" if abs(mean[o] - mean[best]) > std[o] + std[best] else "within"
        for o in OBJECTIVES
    }


def test_means_stds_and_marks_match_a_hand_computation(known):
    table = summary_table(collect(known))
    marks = compare_marks(table)
    assert list(table.index) == OBJECTIVES
    for (n, p), values in COLUMNS.items():
        for o in OBJECTIVES:
            assert table.loc[o, (n, p, "mean")] == pytest.approx(np.mean(values[o]), rel=1e-12)
            assert table.loc[o, (n, p, "std")] == pytest.approx(np.std(values[o], ddof=1), rel=1e-12)
        assert marks[(n, p)].to_dict() == _by_hand(values)
    # the cases are what their comments say
    assert marks[(0.0, "p1")].to_dict() == {"labelled": "best", "hybrid": "worse", "combined": "within"}
    gap = np.mean(COLUMNS[(0.0, "p1")]["hybrid"]) - 0.12
    assert gap / SPREAD == pytest.approx(1 + EPS, abs=1e-9)
    assert marks[(0.01, "p1")].to_dict() == {"hybrid": "best", "combined": "worse", "labelled": "worse"}
    assert marks[(0.01, "p2")].to_dict() == {"combined": "worse", "hybrid": "best", "labelled": "within"}


def test_markdown_bolds_the_best_daggers_beyond_spread_and_states_the_rule_once(known):
    text = to_markdown(summary_table(collect(known)))
    rows = {r["objective"]: r for r in parse_markdown(text)}
    col = "noise 0 p1 [%]"
    low, high = t_interval_by_hand(LAB)
    assert rows["labelled"][col] == f"**12.00 ± 2.00** [{100 * low:.2f}, {100 * high:.2f}]"
    assert rows["hybrid"][col].endswith(" †")
    assert not rows["combined"][col].startswith("**") and not rows["combined"][col].endswith("†")
    assert plain(rows["hybrid"][col]) == f"{100 * (0.12 + SPREAD * (1 + EPS)):.2f} ± 1.00"
    assert all(r["seeds"] == "3" for r in rows.values())
    under = text.split("\n\n", 1)[1]
    assert under.count("\n") == 1 and "|m_a - m_b| > s_a + s_b" in under and "`objective`" in under
    assert "Warning" not in text  # 3 seeds everywhere


def test_fewer_than_three_seeds_warns_and_a_single_seed_is_never_daggered(tmp_path):
    for objective, seeds in [("labelled", [0, 1]), ("hybrid", [0])]:
        for seed in seeds:
            value = {"labelled": [0.1, 0.11], "hybrid": [0.9]}[objective][seed]
            make_run(
                tmp_path / f"{objective}{seed}",
                [f"objective={objective}", f"seed={seed}"],
                seed,
                results=known_results({("test", 0.0, "p1"): value}),
            )
    table = summary_table(collect(tmp_path))
    assert compare_marks(table)[(0.0, "p1")].to_dict() == {"labelled": "best", "hybrid": "unknown"}
    text = to_markdown(table)
    rows = {r["objective"]: r for r in parse_markdown(text)}
    assert rows["hybrid"]["noise 0 p1 [%]"] == "90.00"
    assert (rows["hybrid"]["seeds"], rows["labelled"]["seeds"]) == ("1", "2")
    [warning] = [ln for ln in text.splitlines() if ln.startswith("Warning")]
    assert "objective=hybrid (1)" in warning and "objective=labelled (2)" in warning


def test_groups_are_rows_differing_only_in_the_compared_key(tmp_path):
    # objective x road: by default objectives are compared within a road; compare="road" compares roads
    values = {("labelled", "A"): 0.10, ("hybrid", "A"): 0.20, ("labelled", "E"): 0.40, ("hybrid", "E"): 0.30}
    for (objective, road), v in values.items():
        for seed in range(3):
            make_run(
                tmp_path / f"{objective}{road}{seed}",
                [f"objective={objective}", f"road={road}", f"seed={seed}"],
                seed,
                results=known_results({("test", 0.0, "p1"): v + 0.001 * seed}),
            )
    table = summary_table(collect(tmp_path))
    by_objective = compare_marks(table)[(0.0, "p1")].to_dict()
    assert by_objective == {
        ("hybrid", "A"): "worse",
        ("labelled", "A"): "best",
        ("hybrid", "E"): "best",
        ("labelled", "E"): "worse",
    }
    by_road = compare_marks(table, compare="road")[(0.0, "p1")].to_dict()
    assert by_road == {
        ("hybrid", "A"): "best",
        ("labelled", "A"): "best",
        ("hybrid", "E"): "worse",
        ("labelled", "E"): "worse",
    }
    assert "`road`" in to_markdown(table, compare="road")
    with pytest.raises(ValueError, match="compare = 'seed' is not allowed: a row key"):
        compare_marks(table, compare="seed")


def test_windows_column_and_k_level_only_when_several_k(tmp_path):
    # old records (no windows field) and new ones with K = 1 and K = 8
    for seed in range(2):
        make_run(
            tmp_path / "old" / str(seed),
            ["objective=labelled", f"seed={seed}"],
            seed,
            results=known_results({("test", 0.0, "p1"): 0.1 + seed / 100}),
        )
        make_run(
            tmp_path / "new" / str(seed),
            ["objective=hybrid", f"seed={seed}"],
            seed,
            results=known_results(
                {("test", 0.0, 1, "p1"): 0.2 + seed / 100, ("test", 0.0, 8, "p1"): 0.05 + seed / 100}
            ),
        )
    df = collect(tmp_path)
    assert df.windows.tolist().count(1) == 4 and df.windows.tolist().count(8) == 2
    write_summary(tmp_path / "out", paths=[tmp_path], figures=False)
    csv = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert sorted(csv.windows.unique()) == [1, 8]
    table = summary_table(df)
    assert list(table.index.names) == ["objective", "K"]
    assert list(table.index) == [("hybrid", 1), ("hybrid", 8), ("labelled", 1), ("labelled", 8)]
    assert table[("n_seeds", "", "")].tolist() == [2, 2, 2, 0]  # labelled was evaluated at K = 1 only
    assert table.loc[("hybrid", 8), (0.0, "p1", "mean")] == pytest.approx(np.mean([0.05, 0.06]))
    # objectives are compared at the same K: at K = 8 there is nothing to compare hybrid with
    marks = compare_marks(table)[(0.0, "p1")].to_dict()
    assert marks == {("hybrid", 1): "worse", ("hybrid", 8): "", ("labelled", 1): "best", ("labelled", 8): ""}
    rows = parse_markdown(to_markdown(table))
    assert [(r["objective"], r["K"]) for r in rows] == [
        ("hybrid", "1"),
        ("hybrid", "8"),
        ("labelled", "1"),
        ("labelled", "8"),
    ]


def test_a_single_k_changes_nothing_visible_but_is_named(tmp_path):
    for seed in range(2):
        for objective in ("labelled", "hybrid"):
            make_run(
                tmp_path / f"{objective}{seed}",
                [f"objective={objective}", f"seed={seed}"],
                seed,
                results=known_results({("test", 0.0, 8, "p1"): 0.1 + seed / 100}),
            )
    df, table = write_summary(tmp_path, figures=False)
    assert list(table.index.names) == ["objective"]
    md = (tmp_path / "summary.md").read_text()
    assert "K = 8" in md and [r["objective"] for r in parse_markdown(md)] == ["hybrid", "labelled"]


def test_latex_marks_escapes_and_notes(known):
    table = summary_table(collect(known))
    tex = to_latex(table, caption="mean relative deviation")
    assert r"\begin{tabular}{lrrrr}" in tex and r"\toprule" in tex and r"\bottomrule" in tex
    lines = tex.splitlines()
    at = next(i for i, ln in enumerate(lines) if ln.startswith("labelled &"))
    labelled, interval = lines[at], lines[at + 1]  # the interval in the line below, in smaller type
    hybrid = next(ln for ln in lines if ln.startswith("hybrid &"))
    low, high = t_interval_by_hand(LAB)
    assert labelled.split(" & ")[1] == r"$\mathbf{12.00 \pm 2.00}$"
    assert interval.split(" & ")[1] == rf"{{\scriptsize $[{100 * low:.2f}, {100 * high:.2f}]$}}"
    assert hybrid.split(" & ")[1].endswith(r"^{\dagger}$")
    assert r"$|m_a - m_b| > s_a + s_b$" in tex and "$^\\dagger$" in tex and r"\caption{" in tex
    renamed = table.rename(index={"hybrid": "ls_window"})
    assert r"ls\_window &" in to_latex(renamed)


def test_seeds_that_agree_have_the_value_as_their_interval():
    """A baseline without randomness gives every seed the same number: scipy's interval would multiply 0 by an
    infinite t and warn; the interval of a constant is the constant."""
    import warnings

    from hybrid_sysid.report.stats import t_interval

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert t_interval([2.5, 2.5, 2.5]) == (2.5, 2.5)


def test_an_interval_never_leaves_the_possible_range_and_keeps_its_upper_end():
    """Two seeds far apart: the t interval of their mean reaches below 0, which no mean relative deviation can.
    The table's interval is the same one cut at 0 (the true mean is never negative, so the coverage is unchanged)."""
    from hybrid_sysid.report.stats import t_interval

    far = [0.05, 0.6]
    low, high = t_interval_by_hand(far)
    assert low < 0  # the case: an uncut interval leaves the range
    assert t_interval(far) == (0.0, pytest.approx(high, rel=1e-12))
    close = [0.10, 0.12, 0.11]
    assert t_interval(close) == pytest.approx(t_interval_by_hand(close), rel=1e-12)
