"""experiment=tuned (hybrid_sysid.experiments.tuned): the search space read from Hydra's sweep syntax, trial 0
is the defaults, the tuned runs carry the best trial's values (the lowest recorded validation figure), a hybrid search
never reads labels, a re-run trains nothing, and the sweep as a user runs it ends with a table of the default and
tuned runs only and the searches' table."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import yaml
from omegaconf import OmegaConf

from helpers.started_early import started_early

optuna = pytest.importorskip("optuna", reason='needs the search extra: pip install -e ".[search]"')

from hybrid_sysid.config import ConfigError  # noqa: E402
from hybrid_sysid.experiments.presets import preset  # noqa: E402
from hybrid_sysid.experiments.search import search_space  # noqa: E402
from hybrid_sysid.experiments.tuned import defaults_in, run_tuned  # noqa: E402

TINY = [
    "experiment=tuned",
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=10",
    "trainer.eval_every_n_steps=5",
    "tuned.n_trials=3",
    "tuned.seeds=[0]",
    "evaluation.windows=[1]",
]


def test_the_space_is_the_presets_text_as_optuna_distributions():
    from optuna.distributions import CategoricalDistribution as C
    from optuna.distributions import FloatDistribution as F

    # the reference: conf/hparams_search/fast_cnn.yaml's params, written out by hand
    assert search_space(preset("hparams_search", "fast_cnn", "test").hydra.sweeper.params) == {
        "model.optim.lr": F(0.002, 0.05, log=True),
        "model.optim.weight_decay": F(0.0001, 0.1, log=True),
        "model.net.channels": C([16, 32, 48]),
        "model.net.kernel_size": C([5, 7, 9, 11]),
        "model.optim.warmup_fraction": F(0.1, 0.5),
    }
    # Hydra reads an interval's bounds as floats, integers included
    others = {"a": "interval(1, 4)", "b": "tag(log, interval(1, 100))", "c": "choice(x, y)"}
    assert search_space(others) == {"a": F(1.0, 4.0), "b": F(1.0, 100.0, log=True), "c": C(["x", "y"])}
    with pytest.raises(ConfigError, match=r"hydra.sweeper.params.a = 'range\(1,4\)' is not allowed"):
        search_space({"a": "range(1,4)"})


def test_defaults_outside_the_space_are_one_named_error(make_cfg, tmp_path):
    space = search_space(preset("hparams_search", "fast_cnn", "test").hydra.sweeper.params)
    cfg = make_cfg("experiment=tuned")
    assert defaults_in(cfg, space)["model.net.channels"] == cfg.model.net.channels
    with pytest.raises(
        ConfigError,
        match=r"model.net.channels = 64 is not allowed: a value inside the search's space with experiment=tuned",
    ):
        defaults_in(make_cfg("experiment=tuned", "model.net.channels=64"), space)
    # a job refuses them before its first trial: nothing made
    with pytest.raises(ConfigError, match=r"model.net.channels = 64 is not allowed"):
        run_tuned(make_cfg(*TINY, "model.net.channels=64"), tmp_path / "job")
    with pytest.raises(ConfigError, match=r"tuned.n_trials = 0 is not allowed: must be an integer >= 1"):
        run_tuned(make_cfg(*TINY, "tuned.n_trials=0"), tmp_path / "job")
    # a bad later seed too, before the search, in the words of the run's own seed
    with pytest.raises(ConfigError, match=r"tuned.seeds\[1\] = -1 is not allowed: must lie in \[0, 4294967295\]"):
        run_tuned(make_cfg(*TINY, "tuned.seeds=[0,-1]"), tmp_path / "job")
    assert not (tmp_path / "job").exists()


def saved(run_dir) -> dict:
    return OmegaConf.to_container(OmegaConf.load(run_dir / ".hydra" / "config.yaml"))


def value(cfg: dict, dotted: str):
    for part in dotted.split("."):
        cfg = cfg[part]
    return cfg


@pytest.fixture(scope="module")
def hybrid_job(tmp_path_factory):
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR

    tmp = tmp_path_factory.mktemp("tuned")
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(
            config_name="config",
            overrides=[*TINY, "objective=hybrid", f"data.cache_dir={tmp / 'cache'}", "trainer.progress_bar=false"],
        )
    return cfg, run_tuned(cfg, tmp / "job", ["objective=hybrid"]), tmp / "job"


def test_trial_0_is_the_defaults_and_the_tuned_runs_take_the_lowest_validation_figure(hybrid_job):
    cfg, result, job = hybrid_job
    best = yaml.safe_load((job / "search" / "best.yaml").read_text())
    records = [json.loads((job / "search" / str(n) / "metrics.json").read_text()) for n in range(3)]
    assert all(r["monitor"] == "val/loss" for r in records)  # the hybrid objective's label-free figure
    scores = [r["best_score"] for r in records]
    assert best["best"]["trial"] == int(np.argmin(scores)) and best["best"]["value"] == min(scores)
    for key in best["best"]["params"]:
        assert value(saved(job / "search" / "0"), key) == OmegaConf.select(cfg, key)  # trial 0: the defaults
        assert value(saved(job / "default" / "0"), key) == OmegaConf.select(cfg, key)
        assert value(saved(job / "tuned" / "0"), key) == best["best"]["params"][key]
    assert len({tuple(pd.read_csv(job / "search" / "trials.csv").iloc[n, 2:-1]) for n in range(3)}) == 3
    tuned = json.loads((job / "tuned" / "0" / "metrics.json").read_text())
    assert {"tuning=tuned", "seed=0", "objective=hybrid"} == set(tuned["overrides"]) and tuned["seed"] == 0
    assert result["runs"] == ["default/0", "tuned/0"]


def test_a_hybrid_search_never_reads_labels_and_a_rerun_trains_nothing(hybrid_job, tmp_path, poison_labels):
    cfg, _, job = hybrid_job
    stamps = {p: p.stat().st_mtime_ns for p in job.rglob("metrics.json")}
    run_tuned(cfg, job, ["objective=hybrid"])  # everything already there: nothing retrained or rewritten
    assert {p: p.stat().st_mtime_ns for p in job.rglob("metrics.json")} == stamps
    poison_labels()
    run_tuned(cfg, tmp_path / "poisoned", ["objective=hybrid"])
    for name in ("best.yaml", "trials.csv"):  # the same trials, values and choice, to the last digit
        assert (tmp_path / "poisoned" / "search" / name).read_text() == (job / "search" / name).read_text()
    clean = json.loads((job / "tuned" / "0" / "metrics.json").read_text())
    dirty = json.loads((tmp_path / "poisoned" / "tuned" / "0" / "metrics.json").read_text())
    assert clean["best_score"] == dirty["best_score"]
    assert clean["results"] != dirty["results"]  # the poison was there: the scores that use labels differ


def test_a_rerun_rewrites_no_completed_runs_config(hybrid_job):
    cfg, _, job = hybrid_job
    saved = {p: p.read_bytes() for name in ("config.yaml", "overrides.yaml") for p in job.rglob(name)}
    assert len(saved) == 2 * 5  # 3 trials, the default and the tuned run
    # a value that is no override changed (a user's --config-dir file, a preset): every run is already completed,
    # so each keeps the config it was trained with
    changed = OmegaConf.merge(cfg, {"trainer": {"eval_every_n_steps": 2}})
    run_tuned(changed, job, ["objective=hybrid"])
    assert {p: p.read_bytes() for p in saved} == saved


@started_early
def tuned_sweep(tmp, env, tiny_cache):
    """The sweep as a user runs it, then the same command again: real processes (joblib's workers run the jobs).
    Between the two, the job's record is replaced by the "interrupted" one an earlier SIGTERM leaves. What the test
    asserts on: the two processes and the sweep's directory."""
    sweep = tmp / "sweep"
    cli = [
        sys.executable,
        "-m",
        "hybrid_sysid",
        *TINY,
        "tuned.n_trials=1",
        "objective=hybrid",
        "trainer.progress_bar=false",
        f"hydra.sweep.dir={sweep}",
        f"data.cache_dir={tiny_cache}",  # the test run's shared dataset: no simulation in the subprocess
    ]
    proc = subprocess.run(cli, cwd=tmp, env=env, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        return proc, None, sweep
    (sweep / "0" / "metrics.json").write_text('{"status": "interrupted", "error": "interrupted by SIGTERM"}')
    return proc, subprocess.run(cli, cwd=tmp, env=env, capture_output=True, text=True, timeout=600), sweep


@pytest.mark.integration
def test_the_sweep_tables_the_default_and_tuned_runs_and_the_searches(tuned_sweep, tmp_path):
    proc, again, sweep = tuned_sweep
    assert proc.returncode == 0, proc.stderr[-3000:]
    # an earlier SIGTERM leaves the job's own "interrupted" record; the same command, every run done, supersedes it
    assert again.returncode == 0, again.stderr[-3000:]
    assert not (sweep / "0" / "metrics.json").exists()
    summary = pd.read_csv(sweep / "summary.csv")
    assert sorted(summary.run.unique()) == ["0/default/0", "0/tuned/0"]  # the trials are left out
    assert set(summary.tuning) == {"default", "tuned"}
    tuning = (sweep / "tuning.md").read_text()
    assert "val/loss" in tuning and "1/1" in tuning  # the monitor and the completed trials of the search
    assert (sweep / "figures" / "tuning.png").stat().st_size > 0
    from hybrid_sysid.cli.report import main as report

    assert report([sweep, f"out={tmp_path / 'all'}"]) == 0  # without exclude= the trials are rows too
    assert pd.read_csv(tmp_path / "all" / "summary.csv").run.nunique() == 3
    assert report([sweep, f"out={tmp_path / 'some'}", "exclude=*/search/*"]) == 0
    assert pd.read_csv(tmp_path / "some" / "summary.csv").run.nunique() == 2


def test_a_failed_trial_is_recorded_and_the_study_goes_on(make_cfg, tmp_path, monkeypatch):
    from hybrid_sysid.training import run as train_module

    build_model = train_module.build_model

    def failing(cfg, *args):  # the seeded sampler's first draw after the defaults has 16 channels
        if cfg.model.net.channels == 16:
            raise RuntimeError("a failing trial")
        return build_model(cfg, *args)

    monkeypatch.setattr(train_module, "build_model", failing)
    cfg = make_cfg(*TINY, "tuned.n_trials=2")
    run_tuned(cfg, tmp_path / "job", [])
    failed = json.loads((tmp_path / "job" / "search" / "1" / "metrics.json").read_text())
    assert failed["status"] == "failed" and "a failing trial" in failed["error"]
    trials = pd.read_csv(tmp_path / "job" / "search" / "trials.csv")
    assert list(trials.state) == ["COMPLETE", "FAIL"]
    best = yaml.safe_load((tmp_path / "job" / "search" / "best.yaml").read_text())
    assert best["best"]["trial"] == 0 and best["completed"] == 1
    assert saved(tmp_path / "job" / "tuned" / "0")["model"] == saved(tmp_path / "job" / "default" / "0")["model"]
