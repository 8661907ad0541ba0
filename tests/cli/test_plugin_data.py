"""A researcher's data module plugged in by entry point (hybrid_sysid.datasets): the example package of plugins
(tests/plugins/example), installed with pip, gives a seat shaken by sines whose truth is known. From the command
line ``data=sine_seat`` trains a network of the project's on it and scores it there, its config found without
hydra.searchpath; ``hybrid-sysid --help`` lists the package's options beside the project's, and only the
project's where the package is not installed.

pip installs it into a folder of the test's own (``--target``), which the processes find on PYTHONPATH and this
process on sys.path for one test: the environment never sees it, so no other test does."""

import json
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from hybrid_sysid.config import CONF_DIR

from helpers import app_process
from helpers.installed import EXAMPLE, install_example
from helpers.started_early import started_early

pytestmark = pytest.mark.integration

STEPS = 6
RUN = ["data=sine_seat", "trainer=debug", f"trainer.max_steps={STEPS}", "trainer.eval_every_n_steps=3"]
RUN += ["evaluation.windows=[1,2]", "run_figures=false"]
RECORDINGS = 48  # conf/data/sine_seat.yaml's data.module.recordings
PACKAGE = "hybrid-sysid-example-plugin"
HEAVY = ("torch", "lightning", "scipy.signal")  # what --help must not import: seconds of a start
# hybrid-sysid's console script, which says at its end which of HEAVY it imported
HELP = f"""import atexit, json, sys
atexit.register(lambda: sys.stderr.write(json.dumps([m for m in {HEAVY!r} if m in sys.modules])))
from hybrid_sysid.cli.train import main
main()
"""
GROUPS = ("data", "model", "objective")  # the groups the example package adds an option to


def on_path(env: dict, site: Path) -> dict:
    return {**env, "PYTHONPATH": os.pathsep.join(p for p in (str(site), env.get("PYTHONPATH")) if p)}


@started_early
def sine_seat_run(tmp, env):
    """(the run's process, its directory, the --help of a process with the package and of one without it, the
    folder the package is installed in, hybrid-sysid-eval's process on the run and its directory)."""
    site = install_example(tmp)
    run = app_process.run_app(tmp, *RUN, f"hydra.run.dir={tmp / 'run'}", env=on_path(env, site))
    (tmp / "help.py").write_text(HELP)
    helps = [app_process.run_app(tmp, "--help", env=e, script=tmp / "help.py") for e in (on_path(env, site), env)]
    again = [f"run={tmp / 'run'}", f"hydra.run.dir={tmp / 'eval'}"]
    evaluation = app_process.run_app(tmp, *again, env=on_path(env, site), module="hybrid_sysid.cli.evaluate")
    return run, tmp / "run", helps, site, evaluation, tmp / "eval"


def test_a_network_trains_and_is_scored_on_a_plugins_data_module(sine_seat_run):
    proc, run, *_ = sine_seat_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    record = json.loads((run / "metrics.json").read_text())
    assert record["status"] == "completed" and record["steps"] == STEPS
    assert record["plugins"] == {
        "data.module": {
            "class": "hybrid_sysid_example_plugin.datasets.SineSeatDataModule",
            "entry_point": "hybrid_sysid.datasets:sine_seat",
            "package": PACKAGE,
            "version": "0.1.0",
        }
    }
    pred = pd.read_csv(run / "predictions.csv")
    # every recording scored once per evaluation, in one split only: the splits partition the recordings
    first = pred[(pred.noise_std == 0) & (pred.windows == 1)]
    assert sorted(first.recording) == list(range(RECORDINGS)) and not first.recording.duplicated().any()
    evaluations = {(s, float(n), int(k)) for s, n, k in zip(pred.split, pred.noise_std, pred.windows)}
    assert evaluations == {("train", 0, 1), ("val", 0, 1)} | {("test", n, k) for n in (0, 0.01) for k in (1, 2)}
    # the labels are the truth: the paper's car's seat constants over each recording's mass
    car = yaml.safe_load((Path(CONF_DIR) / "car" / "paper.yaml").read_text())
    np.testing.assert_allclose(pred.p1_true, car["c3"] / pred.m3, rtol=1e-12)
    np.testing.assert_allclose(pred.p2_true, car["k3"] / pred.m3, rtol=1e-12)
    assert set(pred.road_class) == {"sine"}
    # the record's test rows are the mean relative deviations of predictions.csv's rows
    test = pred[pred.split == "test"]
    for row in (r for r in record["results"] if r["split"] == "test"):
        rows = test[(test.noise_std == row["noise_std"]) & (test.windows == row["windows"])]
        p = row["parameter"]
        dev = (rows[f"{p}_pred"] - rows[f"{p}_true"]).abs() / rows[f"{p}_true"]
        assert row["n"] == len(rows) > 0 and row["mean_rel_dev"] == pytest.approx(dev.mean(), rel=1e-9)
    assert {r["road_class"] for r in record["by_road_class"]} == {"sine"}


def test_help_lists_the_packages_options_beside_the_projects_and_only_the_projects_without_it(sine_seat_run):
    """The options of the groups the package adds to, against the YAML files of the project and of the package;
    and neither process imports torch, Lightning or scipy.signal for it."""
    _, _, helps, *_ = sine_seat_run
    plugin_conf = EXAMPLE / "src" / "hybrid_sysid_example_plugin" / "conf"
    for proc, dirs in zip(helps, ([Path(CONF_DIR), plugin_conf], [Path(CONF_DIR)])):
        assert proc.returncode == 0 and json.loads(proc.stderr) == [], proc.stderr[-2000:]
        listed = dict(line.split(": ", 1) for line in proc.stdout.splitlines() if line.split(":")[0] in GROUPS)
        for group in GROUPS:
            files = sorted({p.stem for d in dirs for p in (d / group).glob("*.yaml")})
            assert listed[group].split(", ") == files, (group, listed[group])


def test_the_example_recordings_follow_their_seat_equation(sine_seat_run, monkeypatch):
    """The example's truth, from the equations alone: the seat z'' = -p1 x' - p2 x at every sample, and x', x the
    integrals of x'' = z'' - y'' and of x' (the trapezoid rule, exact to O(dt^2) of the step's change)."""
    monkeypatch.syspath_prepend(str(sine_seat_run[3]))
    try:
        from hybrid_sysid_example_plugin.datasets import SineSeatDataModule

        dt = 0.005
        dm = SineSeatDataModule(window=200, n_steps=400, dt=dt, m3_min=50, m3_max=200, c3=615.0, k3=98935.0)
        dm.setup()
    finally:
        for name in [m for m in sys.modules if m.startswith("hybrid_sysid_example_plugin")]:
            del sys.modules[name]
    d = dm.dataset
    seat, body, v, x = (getattr(d, k).astype(np.float64) for k in ("seat_acc", "body_acc", "rel_vel", "rel_disp"))
    p1, p2 = d.params[:, :1], d.params[:, 1:]
    assert np.abs(seat + p1 * v + p2 * x).max() / np.abs(seat).max() < 1e-5  # float32's rounding: 7e-8 measured
    for rate, level in ((seat - body, v), (v, x)):
        step = np.diff(level, axis=1)
        trapezoid = dt / 2 * (rate[:, 1:] + rate[:, :-1])
        # the rule's error on a sine of w is (w dt)^2 / 12 of its step: 1.3e-3 at the band's top, 4 Hz (1.06e-3
        # measured); a wrong sign or derivative is of the order of the step
        assert np.abs(step - trapezoid).max() < 3e-3 * np.abs(step).max()


def test_hybrid_sysid_eval_scores_the_trained_network_on_the_data_module_again(sine_seat_run):
    """The same config, seed and weights on the same data module: the same numbers, to the last digit."""
    proc, run, _, _, evaluation, again = sine_seat_run
    assert proc.returncode == 0 and evaluation.returncode == 0, evaluation.stderr[-3000:]
    trained, scored = (json.loads((d / "metrics.json").read_text()) for d in (run, again))
    assert scored["status"] == "completed" and scored["source_run"] == str(run)
    assert scored["plugins"] == trained["plugins"]
    assert [r for r in scored["results"] if r["split"] == "test"] == [
        r for r in trained["results"] if r["split"] == "test"
    ]
