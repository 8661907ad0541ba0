"""experiment=anchored's table and figure: rows (fault, estimator), one line per estimator against the noise
level, least squares dashed, the values the mean over seeds of what the runs recorded."""

import numpy as np

from hybrid_sysid.report.anchored_figure import FLOOR, anchored_figure
from hybrid_sysid.report.summary import write_summary

from helpers.evaluation_fakes import known_results, make_run

NOISE = (0.0, 0.01, 0.03)
# per (fault, estimator): the mean relative deviation at each noise level; seed s adds 0.001 * s
VALUES = {
    ("clean", "ls"): (0.0, 0.06, 0.16),
    ("clean", "anchored_label_free"): (0.0, 0.05, 0.11),
    ("skewed", "ls"): (0.12, 0.15, 0.2),
    ("skewed", "anchored_label_free"): (0.05, 0.08, 0.12),
}
SEEDS = (0, 1)


def make_sweep(root):
    for i, ((fault, estimator), values) in enumerate(VALUES.items()):
        for seed in SEEDS:
            results = {("test", n, p): v + 0.001 * seed for n, v in zip(NOISE, values) for p in ("p1", "p2")}
            make_run(
                root / f"{i}_{seed}",
                ["experiment=anchored", f"fault={fault}", f"estimator={estimator}", f"seed={seed}"],
                seed,
                results=known_results(results),
            )
    return root


def test_one_line_per_estimator_against_noise_least_squares_dashed(tmp_path, drawn):
    _, table = write_summary(make_sweep(tmp_path / "sweep"), figures=False)
    assert list(table.index.names) == ["fault", "estimator"]
    anchored_figure(table, tmp_path / "anchored.png")
    assert (tmp_path / "anchored.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig = drawn["anchored"]
    assert sorted(ax.get_title() for ax in fig.axes) == sorted(
        f"{f}: {p}" for f in ("clean", "skewed") for p in ("p1", "p2")
    )
    for ax in fig.axes:
        fault = ax.get_title().split(":")[0]
        lines = {c.get_label(): c.lines[0] for c in ax.containers}  # each errorbar's data line, by its label
        assert sorted(lines) == ["anchored_label_free", "ls"]
        assert lines["ls"].get_linestyle() == "--" and lines["anchored_label_free"].get_linestyle() == "-"
        for name, line in lines.items():
            expected = 100 * (np.array(VALUES[(fault, name)]) + 0.0005)  # mean over the two seeds, in percent
            np.testing.assert_allclose(
                np.asarray(line.get_ydata(), dtype=float), np.maximum(expected, FLOOR), rtol=1e-9
            )
    assert len(fig.legends) == 1


def test_the_sweep_summary_draws_it(tmp_path):
    sweep = make_sweep(tmp_path / "sweep")
    write_summary(sweep)
    assert (sweep / "figures" / "anchored.png").exists()
