"""Hyperparameter search (conf/hparams_search, the study sweeper of hybrid_sysid.launch.search) as a user runs it (a
subprocess where a signal ends it, else the command's main() in this process): a seeded 3-trial study completes
with finite values, each trial's value is its job's model-selection figure, a failed trial is recorded and the
study goes on, the best parameters are written beside the sweep, a search terminated during a trial and run again
ends with the trials and values of an uninterrupted one, and a search over the hybrid objective never reads
labels."""

import json
import math
import os
import signal
import subprocess
import sys
import textwrap

import pytest
import yaml

from helpers.started_early import started_early

optuna = pytest.importorskip("optuna", reason='needs the search extra: pip install -e ".[search]"')

pytestmark = pytest.mark.integration

TINY = [
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=10",
    "trainer.eval_every_n_steps=5",
    "trainer.curve_every_n_steps=null",
    "trainer.progress_bar=false",
    "hydra.sweeper.n_trials=3",
]

# the app with every label replaced by noise: the training windows, validation and test all see the poison
POISONED = textwrap.dedent("""
    import torch
    from hybrid_sysid.data import datamodule
    init = datamodule.WindowCutter.__init__
    def poisoned(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self.params = torch.rand(self.params.shape, generator=torch.Generator().manual_seed(1)) * 50
    datamodule.WindowCutter.__init__ = poisoned
    from hybrid_sysid.cli.train import main
    main()
""")


# the app with one trial failing: the first (job 0)
FAILING = textwrap.dedent("""
    from hydra.core.hydra_config import HydraConfig
    from hybrid_sysid.training import run as train
    build_model = train.build_model
    def failing(cfg):
        if HydraConfig.get().job.num == 0:
            raise RuntimeError("a failing trial")
        return build_model(cfg)
    train.build_model = failing
    from hybrid_sysid.cli.train import main
    main()
""")


# the app sending itself a SIGTERM during the 5th training step of job 1 (the basic launcher runs the jobs in the
# search's own process)
TERMINATED = textwrap.dedent("""
    import os
    import signal
    from hydra.core.hydra_config import HydraConfig
    from hybrid_sysid.training import run as train
    build_model = train.build_model
    def build(cfg, *args):
        model = build_model(cfg, *args)
        if HydraConfig.get().job.num == 1:
            step, calls = model.training_step, []
            def terminated(*args, **kwargs):
                calls.append(1)
                if len(calls) == 5:
                    os.kill(os.getpid(), signal.SIGTERM)
                return step(*args, **kwargs)
            model.training_step = terminated
        return model
    train.build_model = build
    from hybrid_sysid.cli.train import main
    main()
""")


def command(tmp_path, name, *args, script=None, cache=None) -> list[str]:
    app = [sys.executable, str(script)] if script else [sys.executable, "-m", "hybrid_sysid"]
    sweep = tmp_path / name
    return [
        *app,
        "hparams_search=fast_cnn",
        *TINY,
        f"hydra.sweep.dir={sweep}",
        f"data.cache_dir={cache or tmp_path / 'cache'}",
        *args,
    ]


def results(sweep):
    """The study (its default storage: study.db in the sweep directory) and each trial's record."""
    study = optuna.load_study(study_name="fast_cnn", storage=f"sqlite:///{sweep / 'study.db'}")
    records = [json.loads((sweep / str(t.number) / "metrics.json").read_text()) for t in study.trials]
    return study, records


def dotted(config: dict, key: str):
    """The value at a dotted key of a saved config."""
    for part in key.split("."):
        config = config[part]
    return config


def search(tmp_path, name, *args, script=None, status=0, cache=None):
    env = {**os.environ, "HYDRA_FULL_ERROR": "0"}
    cli = command(tmp_path, name, *args, script=script, cache=cache)
    proc = subprocess.run(cli, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == status, proc.stderr[-3000:]
    return tmp_path / name, *results(tmp_path / name)


@pytest.mark.slow  # by default: a failed trial's tell in process (test_search_space.py), values against records below
def test_a_labelled_search_scores_trials_by_val_rel_dev_and_goes_on_past_a_failed_trial(tmp_path):
    script = tmp_path / "failing.py"
    script.write_text(FAILING)
    sweep, study, records = search(tmp_path, "labelled", "objective=labelled", script=script, status=1)
    assert [t.state.name for t in study.trials] == ["FAIL", "COMPLETE", "COMPLETE"]
    assert records[0]["status"] == "failed" and "a failing trial" in records[0]["error"]
    for trial, record in zip(study.trials[1:], records[1:]):
        assert record["monitor"] == "val/rel_dev" and math.isfinite(trial.value)
        assert trial.value == pytest.approx(record["best_score"])
        for key, value in trial.params.items():  # the job ran the trial's parameters
            assert any(
                o.split("=")[0] == key and float(o.split("=")[1]) == pytest.approx(value) for o in record["overrides"]
            )
    best = yaml.safe_load((sweep / "optimization_results.yaml").read_text())
    assert best["best_value"] == pytest.approx(min(r["best_score"] for r in records[1:]))
    assert best["best_params"] == study.best_params
    summary = (sweep / "summary.md").read_text()  # the sweep summary works on a search's directory too
    assert "a failing trial" in summary


def in_process(cli_in_process, tmp_path, name, *args, cache):
    """The search as search() runs it, through the command's main() in this process: (sweep, study, records)."""
    from hybrid_sysid.cli.train import main

    code, _, err = cli_in_process(main, *command(tmp_path, name, *args, cache=cache)[3:], cwd=tmp_path)
    assert code == 0, err[-3000:]
    return tmp_path / name, *results(tmp_path / name)


LONGER = ["trainer.max_steps=40", "trainer.eval_every_n_steps=10", "hydra.sweeper.sampler.n_startup_trials=1"]


@started_early
def cut_search(tmp, env, tiny_cache):
    """A fresh process, sending itself a SIGTERM at trial 1's 5th step (trial 0 random, 1 and 2 from TPE): the
    signal, its exit status and the study it leaves are what is tested."""
    script = tmp / "terminated.py"
    script.write_text(TERMINATED)
    cut_cli = command(tmp, "cut", *LONGER, script=script, cache=tiny_cache)
    return subprocess.run(cut_cli, cwd=tmp, env=env, capture_output=True, text=True, timeout=900), tmp


def test_a_search_terminated_during_a_trial_resumes_to_the_uninterrupted_trials(
    tmp_path, tiny_cache, cli_in_process, cut_search
):
    # the uninterrupted search and the re-run in this process (nothing of theirs is about a process); the
    # terminated one in a fresh process (cut_search)
    whole, study, records = in_process(cli_in_process, tmp_path, "whole", *LONGER, cache=tiny_cache)
    assert [t.state.name for t in study.trials] == ["COMPLETE"] * 3

    # the same search, terminated during trial 1
    search_proc, where = cut_search
    assert search_proc.returncode == 128 + signal.SIGTERM, search_proc.stderr[-3000:]
    cut = optuna.load_study(study_name="fast_cnn", storage=f"sqlite:///{where / 'cut' / 'study.db'}")
    assert [t.state.name for t in cut.trials] == ["COMPLETE", "RUNNING"]  # trial 1 left for the re-run
    assert json.loads((where / "cut" / "1" / "metrics.json").read_text())["status"] == "interrupted"

    # the same command again: exit 0
    again, resumed, resumed_records = in_process(cli_in_process, where, "cut", *LONGER, cache=tiny_cache)
    assert [t.number for t in resumed.trials] == [0, 1, 2]
    assert [t.params for t in resumed.trials] == [t.params for t in study.trials]
    assert [t.value for t in resumed.trials] == [t.value for t in study.trials]  # identical, not close
    for trial, a, b, trial_dir in zip(study.trials, records, resumed_records, sorted(again.glob("[0-9]"))):
        differ = [(ra, rb) for ra, rb in zip(a["results"], b["results"]) if ra != rb]
        assert b["status"] == "completed" and not differ, f"trial {trial.number}: {differ[:2]}"
        assert trial.value == b["best_score"] and b["monitor"] == "val/rel_dev"  # its model-selection figure
        # each trial's directory holds the config of the run it recorded, with the trial's values
        assert yaml.safe_load((trial_dir / ".hydra" / "overrides.yaml").read_text()) == b["overrides"]
        saved = yaml.safe_load((trial_dir / ".hydra" / "config.yaml").read_text())
        for key, value in trial.params.items():
            assert dotted(saved, key) == pytest.approx(value), key
    best = yaml.safe_load((again / "optimization_results.yaml").read_text())
    assert best["best_value"] == min(t.value for t in study.trials) and best["completed"] == 3


# a Hydra callback (+hydra.callbacks.cut): the job of trial ``trial``, in its parallel worker, sends the search's
# process a SIGTERM at its 5th training step, as a user's kill would come; Hydra pickles the callback into the worker
CUT_TRIAL = textwrap.dedent("""
    import os
    import signal
    from hydra.experimental.callback import Callback

    class CutTrial(Callback):
        def __init__(self, trial):
            self.trial, self.search = trial, os.getpid()  # made in the search's process

        def on_job_start(self, config, **kwargs):
            if config.hydra.job.num != self.trial:
                return
            from hybrid_sysid.training import run as train
            build_model, search = train.build_model, self.search
            def build(cfg, *args):
                model = build_model(cfg, *args)
                step, calls = model.training_step, []
                def terminated(*args, **kwargs):
                    calls.append(1)
                    if len(calls) == 5:
                        os.kill(search, signal.SIGTERM)
                    return step(*args, **kwargs)
                model.training_step = terminated
                return model
            train.build_model = build
""")
PARALLEL = [*LONGER, "launcher=joblib", "hydra.sweeper.n_jobs=2"]


@pytest.mark.slow  # about a minute (three searches of 5 trials); by default the same promise without a launcher above
def test_a_parallel_search_terminated_during_a_trial_resumes_to_the_uninterrupted_trials(tmp_path, tiny_cache):
    hooks = tmp_path / "hooks"
    hooks.mkdir()
    (hooks / "cut_trial.py").write_text(CUT_TRIAL)
    path = os.pathsep.join(filter(None, [str(hooks), os.environ.get("PYTHONPATH")]))  # the workers inherit it
    env = {**os.environ, "HYDRA_FULL_ERROR": "0", "PYTHONPATH": path}

    def run(name, *extra):
        cli = [a for a in command(tmp_path, name, *PARALLEL, cache=tiny_cache) if "sweeper.n_trials=" not in a]
        cli += ["hydra.sweeper.n_trials=5", *extra]  # batches {0, 1}, {2, 3}, {4}
        return subprocess.run(cli, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)

    proc = run("whole")
    assert proc.returncode == 0, proc.stderr[-3000:]
    study, records = results(tmp_path / "whole")
    assert [t.state.name for t in study.trials] == ["COMPLETE"] * 5

    # the same search, terminated during trial 3 (trial 2 beside it, running or just done)
    proc = run("cut", "+hydra.callbacks.cut._target_=cut_trial.CutTrial", "+hydra.callbacks.cut.trial=3")
    assert proc.returncode == 128 + signal.SIGTERM, proc.stderr[-3000:]
    cut, _ = results(tmp_path / "cut")
    states = [t.state.name for t in cut.trials]
    assert states[:2] == ["COMPLETE"] * 2 and states[3] == "RUNNING" and len(states) == 4  # trial 4 never asked
    assert json.loads((tmp_path / "cut" / "3" / "metrics.json").read_text())["status"] == "interrupted"

    # the same command again: exit 0, the study and records of the uninterrupted search
    proc = run("cut")
    assert proc.returncode == 0, proc.stderr[-3000:]
    resumed, resumed_records = results(tmp_path / "cut")
    assert [t.number for t in resumed.trials] == [0, 1, 2, 3, 4]
    assert [t.params for t in resumed.trials] == [t.params for t in study.trials]
    assert [t.value for t in resumed.trials] == [t.value for t in study.trials]  # identical, not close
    for n, (a, b) in enumerate(zip(records, resumed_records)):
        differ = [(ra, rb) for ra, rb in zip(a["results"], b["results"]) if ra != rb]
        assert b["status"] == "completed" and not differ, f"trial {n}: {differ[:2]}"
        overrides = yaml.safe_load((tmp_path / "cut" / str(n) / ".hydra" / "overrides.yaml").read_text())
        assert overrides == b["overrides"]  # each trial's directory holds the config of the run it recorded
        saved = yaml.safe_load((tmp_path / "cut" / str(n) / ".hydra" / "config.yaml").read_text())
        assert all(dotted(saved, k) == pytest.approx(v) for k, v in resumed.trials[n].params.items())


@pytest.mark.slow  # by default: test_tuned.py's hybrid search (same TPE, same val/loss) with poisoned labels
def test_a_hybrid_search_never_reads_labels(tmp_path):
    script = tmp_path / "poisoned.py"
    script.write_text(POISONED)
    _, clean, clean_records = search(tmp_path, "clean", "objective=hybrid")
    _, poisoned, poisoned_records = search(tmp_path, "poisoned", "objective=hybrid", script=script)
    assert all(r["monitor"] == "val/loss" for r in clean_records + poisoned_records)
    assert all(t.state.name == "COMPLETE" and math.isfinite(t.value) for t in clean.trials)
    assert len(clean.trials) == 3
    assert [t.params for t in clean.trials] == [t.params for t in poisoned.trials]
    assert [t.value for t in clean.trials] == [t.value for t in poisoned.trials]  # identical, not close
    # while the poison did reach the labels: the labelled figures of the same runs differ
    dev = lambda rec: [r["mean_rel_dev"] for r in rec["results"] if r["split"] == "val"]  # noqa: E731
    assert all(dev(a) != pytest.approx(dev(b)) for a, b in zip(clean_records, poisoned_records))
