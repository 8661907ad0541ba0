"""``run_figures``: who draws a run's figures/ (a single run, not a sweep's jobs, by default), its check, and
``hybrid-sysid-report PATH run_figures=true``, which draws them afterwards for every completed run."""

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.cli import report
from hybrid_sysid.config import ConfigError, validate
from hybrid_sysid.launch.job import draws_figures

from helpers.evaluation_fakes import make_run


def test_auto_draws_for_a_single_run_and_not_for_a_sweeps_jobs():
    assert draws_figures("auto", multirun=False) and not draws_figures("auto", multirun=True)
    assert draws_figures(True, multirun=True) and not draws_figures(False, multirun=False)


@pytest.mark.parametrize("value", ["sometimes", 1])
def test_a_bad_value_is_named(make_cfg, value):
    with pytest.raises(ConfigError, match=f"run_figures = {value!r} is not allowed: true, false or auto"):
        validate(make_cfg(f"run_figures={value}"))
    validate(make_cfg("run_figures=false"))  # the other values pass


def _predictions(seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for std in (0.0, 0.01):
        for k in (1, 8):
            true = rng.uniform(3, 12, size=(40, 2)) * [1, 160]
            pred = true * (1 + rng.normal(0, 0.02 + std, size=true.shape))
            rows.append(
                pd.DataFrame(
                    {"split": "test", "noise_std": std, "windows": k, "recording": range(40), "road_class": "A",
                     "m3": 100.0, "p1_true": true[:, 0], "p1_pred": pred[:, 0], "p2_true": true[:, 1],
                     "p2_pred": pred[:, 1]}
                )
            )  # fmt: skip
    return pd.concat(rows, ignore_index=True)


def test_the_report_draws_every_completed_runs_figures_on_request(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    for job, seed in enumerate((0, 1)):
        run = make_run(sweep / str(job), [f"seed={seed}"], seed)
        _predictions(seed).to_csv(run / "predictions.csv", index=False)
    make_run(sweep / "2", ["seed=2"], 2, status="failed", error="RuntimeError: boom")

    assert report.main([str(sweep)]) == 1  # a failed run: exit 1, everything still written
    assert not any((sweep / job / "figures").exists() for job in ("0", "1", "2"))  # not without asking

    assert report.main([str(sweep), "run_figures=true"]) == 1
    assert "drew the figures of 2 runs" in capsys.readouterr().err
    for job in ("0", "1"):
        for name in ("test_predictions.png", "learning_curves.png"):
            assert (sweep / job / "figures" / name).stat().st_size > 10_000
    assert not (sweep / "2" / "figures").exists()  # a failed run has nothing to draw
