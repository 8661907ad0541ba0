"""experiment=anchored's targets table (report/anchored_targets.py): runs whose per-recording deviations are
a known factor of a reference's give that factor as the ratio, its interval and the goal's verdict; the reference
"best classical" is the classical fit with the lowest mean; a fault's noise-free goal asks exactness where the
fixed fit is exact."""

import re

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from hybrid_sysid.report.anchored_targets import ratio_interval, targets_markdown

from helpers.evaluation_fakes import known_results, make_run

NOISE = (0.0, 0.003, 0.01, 0.03, 0.1)
N = 60  # recordings


def base_devs(seed: int) -> np.ndarray:
    """(N,) positive deviations of the reference on each recording."""
    return np.random.default_rng(seed).uniform(0.01, 0.2, N)


# per (fault, estimator): per noise level, per parameter, a factor of base_devs (None: 0, exact)
FACTORS = {
    ("clean", "eiv"): {n: (1.0, 1.0) for n in NOISE},
    ("clean", "eiv_map"): {n: (0.8, 1.5) for n in NOISE},
    ("clean", "ls"): {n: (1.3, 0.7) for n in NOISE},
    ("clean", "anchored_cross_segment"): {
        0.0: (None, None),
        0.003: (1.02, 1.0),  # within 1.03x the likelihood fit
        0.01: (1.10, 0.9),  # p1 beyond it
        0.03: (0.78, 1.6),  # p1 below the MAP fit's 0.8, p2 above its 1.5
        0.1: (0.5, 0.6),  # p2 below the best classical (ls, 0.7)
    },
    ("gain", "eiv_fix"): {n: (None, None) if n == 0 else (1.0, 1.0) for n in NOISE},
    ("gain", "anchored_cross_segment"): {n: (0.5, 0.5) if n == 0 else (1.05, 1.2) for n in NOISE},
}


def make_sweep(root):
    for i, ((fault, estimator), factors) in enumerate(FACTORS.items()):
        for seed in (0, 1):
            run = make_run(
                root / f"{i}_{seed}",
                ["experiment=anchored", f"fault={fault}", f"estimator={estimator}", f"seed={seed}"],
                seed,
                results=known_results({("test", n, p): 0.1 for n in NOISE for p in ("p1", "p2")}, n=N),
            )
            rows = []
            for n, pair in factors.items():
                devs = [np.zeros(N) if f is None else f * base_devs(seed) for f in pair]
                true = np.stack([np.linspace(3, 9, N), np.linspace(400, 1800, N)], axis=1)
                pred = true * (1 + np.stack(devs, axis=1))
                for r in range(N):
                    rows.append(["test", n, 1, r, "C", 100.0, true[r, 0], pred[r, 0], true[r, 1], pred[r, 1]])
            columns = ["split", "noise_std", "windows", "recording", "road_class", "m3"]
            columns += ["p1_true", "p1_pred", "p2_true", "p2_pred"]
            pd.DataFrame(rows, columns=columns).to_csv(run / "predictions.csv", index=False)
    return root


def table_rows(text: str) -> dict[tuple, list[str]]:
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 11 and cells[0] in ("clean", "gain"):
            rows[(cells[0], float(cells[1]), cells[2])] = cells[3:]
    return rows


def test_each_goal_reads_its_ratio_interval_and_verdict(tmp_path):
    rows = table_rows(targets_markdown([make_sweep(tmp_path / "sweep")]))
    value, reference, ref_value, ratio, goal, met, p, pairs = rows[("clean", 0.003, "p1")]
    assert pairs == str(2 * N)  # two seeds' recordings
    assert (reference, goal, met) == ("eiv", "<= 1.03x", "yes")
    assert ratio == "1.020 [1.020, 1.020]"  # every pair is exactly 1.02x
    a = np.concatenate([1.02 * base_devs(s) for s in (0, 1)])
    b = np.concatenate([base_devs(s) for s in (0, 1)])
    assert float(p) == pytest.approx(stats.wilcoxon(a, b).pvalue, rel=0.01)
    assert float(value) == pytest.approx(100 * a.mean(), abs=0.005)
    assert rows[("clean", 0.01, "p1")][5] == "**no**" and rows[("clean", 0.01, "p2")][5] == "yes"
    assert (
        rows[("clean", 0.03, "p1")][1:5] == ["eiv_map", rows[("clean", 0.03, "p1")][2], "0.975 [0.975, 0.975]", "<= 1x"]
        and rows[("clean", 0.03, "p1")][5] == "yes"
    )
    assert rows[("clean", 0.03, "p2")][5] == "**no**"
    best = rows[("clean", 0.1, "p2")]
    assert best[1] == "ls" and best[3].startswith("0.857") and best[5] == "yes"  # 0.6 / 0.7, against ls
    assert rows[("clean", 0.0, "p1")][5] == "yes"  # exact
    assert rows[("clean", 0.1, "p1")][4] == "<= 18.50%"
    # an absolute limit: the value over it, and its interval about as wide as the normal one of the mean's
    a = np.concatenate([0.5 * base_devs(s) for s in (0, 1)])
    ratio, low, high = (float(x) for x in re.findall(r"[\d.]+", rows[("clean", 0.1, "p1")][3]))
    half = 1.96 * a.std(ddof=1) / np.sqrt(len(a)) / 0.185
    assert ratio == pytest.approx(a.mean() / 0.185, abs=5e-4) and low < ratio < high
    assert high - low == pytest.approx(2 * half, rel=0.2)
    assert rows[("gain", 0.0, "p1")][4:6] == ["<= 0.01%", "**no**"]  # the fixed fit is exact there, it is not
    assert rows[("gain", 0.03, "p1")][4:6] == ["<= 1.1x", "yes"] and rows[("gain", 0.03, "p2")][5] == "**no**"


def test_the_interval_covers_the_ratio_of_means_and_repeats():
    rng = np.random.default_rng(3)
    b = rng.uniform(0.01, 0.2, 400)
    a = b * rng.uniform(0.8, 1.4, 400)
    low, high = ratio_interval(a, b)
    assert low < a.mean() / b.mean() < high and (low, high) == ratio_interval(a, b)


def test_no_table_without_a_label_free_anchored_run(tmp_path):
    root = tmp_path / "sweep"
    make_run(root / "0", ["experiment=anchored", "estimator=ls", "seed=0"], 0)
    assert targets_markdown([root]) == ""


def test_a_job_copied_under_another_number_counts_once(tmp_path):
    import shutil

    sweep = make_sweep(tmp_path / "sweep")
    before = table_rows(targets_markdown([sweep]))
    shutil.copytree(sweep / "3_0", sweep / "9_0")  # anchored_cross_segment, clean, seed 0, again
    assert table_rows(targets_markdown([sweep])) == before


def cut(path, keep_bytes):
    data = path.read_bytes()
    path.write_bytes(data[:keep_bytes])


def notes(text):
    return [line for line in text.splitlines() if line.startswith("- `")]


def test_a_clean_sweep_has_no_note_and_repeated_rows_are_no_cut(tmp_path):
    sweep = make_sweep(tmp_path / "sweep")
    before = targets_markdown([sweep])
    assert notes(before) == [] and table_rows(before)
    p = sweep / "0_0" / "predictions.csv"
    rows = pd.read_csv(p)
    pd.concat([rows, rows]).to_csv(p, index=False)  # P59: the rows doubled are the same recordings
    assert targets_markdown([sweep]) == before


@pytest.mark.parametrize(
    "damage, why",
    [
        ("rows", "holds 57 test recordings at noise 0.1 where its record counts 60"),  # its last 3 rows
        ("bytes", "ends within a row (cut)"),  # cut in the middle of its last rows
        ("300", "ends within a row (cut)"),  # 300 bytes: no test row left, and its last row cut
        ("text", "cannot be read, or holds no test rows at K = 1"),  # P54's p1_pred as text
        ("gone", "is missing"),
    ],
)
def test_a_cut_predictions_file_is_named_and_its_run_left_out(tmp_path, damage, why):
    """P53 (docs/reliability/adversarial_physical_limit.md): a cut file paired fewer recordings in silence. The
    reference: the same sweep without that run's directory, whose targets come from the other seed alone."""
    import shutil

    sweep, reference = make_sweep(tmp_path / "sweep"), make_sweep(tmp_path / "reference")
    shutil.rmtree(reference / "0_0")
    p = sweep / "0_0" / "predictions.csv"  # clean eiv, seed 0: the reference of most goals
    lines = p.read_text().splitlines(keepends=True)
    if damage == "rows":
        p.write_text("".join(lines[:-3]))
    elif damage == "bytes":
        cut(p, len("".join(lines[:-1])) + len(lines[-1]) // 2)
    elif damage == "300":
        cut(p, 300)
    elif damage == "text":
        rows = pd.read_csv(p)
        rows["p1_pred"] = "not a number"
        rows.to_csv(p, index=False)
    else:
        p.unlink()
    text = targets_markdown([sweep])
    assert notes(text) == [f"- `0_0/predictions.csv` {why}: that run is left out of the targets."]
    assert table_rows(text) == table_rows(targets_markdown([reference]))
    assert table_rows(text)[("clean", 0.003, "p1")][-1] == str(N)  # the pairs of seed 1 alone


def test_every_candidate_file_cut_leaves_the_names_not_an_empty_page(tmp_path):
    sweep = make_sweep(tmp_path / "sweep")
    for run in ("3_0", "3_1", "5_0", "5_1"):  # anchored_cross_segment, clean and gain
        cut(sweep / run / "predictions.csv", 300)
    text = targets_markdown([sweep])
    assert text.startswith("No targets of the label-free anchored estimators") and not table_rows(text)
    assert [line.split("`")[1] for line in notes(text)] == [
        f"{r}/predictions.csv" for r in ("3_0", "3_1", "5_0", "5_1")
    ]
