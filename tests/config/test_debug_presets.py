"""The debug group wins over every preset (debug=fast, overfit, profiler), the callbacks group builds the
Lightning callbacks it names, and the paths group moves every output at once."""

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR, ConfigError, validate

EXPERIMENTS = sorted(p.stem for p in (Path(CONF_DIR) / "experiment").glob("*.yaml"))
TINY = {"n_roads": 6, "n_masses": 8, "n_steps": 400, "window": 200}  # conf/data/tiny.yaml


def composed(*overrides, config="config", hydra=False):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name=config, overrides=list(overrides), return_hydra_config=hydra)


def composed_job(cfg):
    """The job's config of a config composed with its hydra node."""
    from omegaconf import OmegaConf

    out = OmegaConf.to_container(cfg, resolve=False)
    out.pop("hydra")
    return OmegaConf.create(out)


def swept_values(cfg, key: str) -> list[str]:
    spec = (cfg.hydra.sweeper.get("params") or {}).get(key)
    return [] if spec is None else str(spec).split(",")


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_debug_fast_shortens_every_experiment(experiment, tmp_path):
    cfg = composed(f"experiment={experiment}", "debug=fast", f"data.cache_dir={tmp_path}", hydra=True)
    t = cfg.trainer
    assert t.max_steps <= 20 and t.eval_every_n_steps <= 10 and t.curve_every_n_steps is None
    assert {k: cfg.data[k] for k in TINY} == TINY
    assert dict(cfg.logger) == {}  # no tracker
    assert len(swept_values(cfg, "seed")) <= 1  # one seed where the preset sweeps several
    if cfg.task == "tuned":
        assert cfg.tuned.n_trials <= 2 and list(cfg.tuned.seeds) == [0]
    if cfg.task == "transfer":
        assert cfg.transfer.adapt_steps <= t.max_steps
    validate(composed_job(cfg))


def test_trainer_debug_shortens_a_single_run_but_a_preset_keeps_its_steps():
    assert composed("data=tiny", "trainer=debug").trainer.max_steps == 20
    # a preset sets its trainer keys after the trainer group (the reason for the debug group)
    assert composed("experiment=paper", "data=tiny", "trainer=debug").trainer.max_steps == 2000
    assert composed("experiment=paper", "debug=fast").trainer.max_steps == 20


def test_debug_fast_wins_over_the_search_preset():
    cfg = composed("hparams_search=fast_cnn", "debug=fast", hydra=True)
    assert cfg.trainer.max_steps == 20 and cfg.trainer.curve_every_n_steps is None
    assert cfg.data.n_roads == TINY["n_roads"]
    assert cfg.hydra.sweeper.n_trials <= 3


def test_the_command_line_wins_over_debug():
    cfg = composed("experiment=tuned", "debug=fast", "tuned.n_trials=5", "trainer.max_steps=7", "data=default")
    assert cfg.tuned.n_trials == 5 and cfg.trainer.max_steps == 7 and cfg.data.n_roads == 40
    assert composed("debug=fast", "logger=csv").logger.csv is not None


def test_overfit_and_profiler_are_fast_plus_their_own_settings():
    overfit, profiler = composed("debug=overfit"), composed("debug=profiler")
    assert overfit.trainer.extra.overfit_batches == 1 and overfit.data.n_roads == TINY["n_roads"]
    assert profiler.trainer.profiler == "simple" and profiler.data.n_roads == TINY["n_roads"]
    assert composed().trainer.profiler is None and "overfit_batches" not in composed().trainer.extra


def _trainer_callbacks(tmp_path, *overrides):
    from hybrid_sysid.training.build import build_callbacks, build_objective, build_trainer, monitor_of

    # progress_bar=true: the bars a terminal gets (the default, auto, shows none when stdout is not one)
    cfg = composed(f"data.cache_dir={tmp_path}", "trainer.progress_bar=true", *overrides)
    validate(cfg)
    monitor = monitor_of(cfg, build_objective(cfg))
    trainer = build_trainer(cfg, tmp_path, build_callbacks(cfg, monitor))
    return {type(c).__name__: c for c in trainer.callbacks}


@pytest.mark.parametrize(
    "overrides, present, absent",
    [
        ([], {"TQDMProgressBar"}, {"EarlyStopping", "ModelSummary", "RichProgressBar"}),  # today's
        (["trainer.progress_bar=false"], set(), {"TQDMProgressBar", "RichProgressBar"}),
        (["callbacks=early_stopping"], {"EarlyStopping", "TQDMProgressBar"}, {"ModelSummary"}),
        (["callbacks=model_summary"], {"ModelSummary", "TQDMProgressBar"}, {"EarlyStopping"}),
        (["callbacks=rich_progress_bar"], {"RichProgressBar"}, {"TQDMProgressBar"}),
        (["callbacks=rich_progress_bar", "trainer.progress_bar=false"], set(), {"RichProgressBar", "TQDMProgressBar"}),
        (["callbacks=[early_stopping,model_summary]"], {"EarlyStopping", "ModelSummary"}, set()),
    ],
)
def test_callbacks_build_their_lightning_classes(tmp_path, overrides, present, absent):
    pytest.importorskip("rich")
    names = set(_trainer_callbacks(tmp_path, *overrides))
    assert present <= names and not absent & names


@pytest.mark.parametrize("objective, monitor", [("labelled", "val/rel_dev"), ("hybrid", "val/loss")])
def test_early_stopping_watches_the_runs_model_selection_figure(tmp_path, objective, monitor):
    stop = _trainer_callbacks(tmp_path, "callbacks=early_stopping", f"objective={objective}")["EarlyStopping"]
    assert stop.monitor == monitor and stop.mode == "min"
    fixed = _trainer_callbacks(tmp_path, "callbacks=early_stopping", "trainer.monitor=val/p1_rel_dev")
    assert fixed["EarlyStopping"].monitor == "val/p1_rel_dev"


@pytest.mark.parametrize(
    "overrides, match",
    [
        (
            ["callbacks=early_stopping", "callbacks.early_stopping._target_=os.system"],
            r"callbacks.early_stopping._target_ = 'os.system' is not allowed: one of lightning.pytorch.callbacks",
        ),
        (["callbacks=early_stopping", "callbacks.early_stopping.monitor=val/acc"], r"monitor = 'val/acc' is not"),
        (["trainer.profiler=fancy"], r"trainer.profiler = 'fancy' is not allowed: one of simple, advanced"),
        (["+paths.nowhere=x"], r"paths.nowhere = 'x' is not allowed: unknown key"),
    ],
)
def test_bad_callbacks_profilers_and_paths_are_named(tmp_path, overrides, match):
    with pytest.raises(ConfigError, match=match):
        validate(composed(f"data.cache_dir={tmp_path}", *overrides))


@pytest.mark.parametrize(
    "overrides, match",
    [
        (["callbacks=early_stopping", "callbacks.early_stopping.mode=sideways"], r"mode. can be min, max"),
        (["callbacks=model_summary", "callbacks.model_summary.max_depth=-7"], r"an integer >= -1"),
        (["callbacks=early_stopping", "+callbacks.early_stopping.bogus=1"], r"bogus = 1 is not allowed: not an arg"),
    ],
)
def test_a_callback_argument_its_class_refuses_is_named_before_any_work(tmp_path, overrides, match):
    """Lightning's own checks of a callback's arguments run in validate, not first in the job after the data are
    simulated and the run directory made (there: a traceback and a failed record)."""
    with pytest.raises(ConfigError, match=r"^callbacks\.\w+.*" + match):
        validate(composed(f"data.cache_dir={tmp_path}", "data=tiny", *overrides))


def test_the_rich_bar_without_rich_is_one_line_naming_the_extra(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "rich" else real(name, *a))
    with pytest.raises(
        ConfigError, match=r'^callbacks.rich_progress_bar is not allowed: it needs the rich package, .*"\.\[rich\]"'
    ):
        validate(composed("data=tiny", "callbacks=rich_progress_bar"))


def test_paths_root_moves_runs_sweeps_cache_and_trackers(monkeypatch):
    monkeypatch.delenv("HYBRID_SYSID_CACHE", raising=False)
    today = composed("logger=mlflow", hydra=True)
    assert today.hydra.run.dir.startswith("outputs/runs/") and today.hydra.sweep.dir.startswith("outputs/multirun/")
    assert today.data.cache_dir == "outputs/.cache"
    assert today.logger.mlflow.tracking_uri == "sqlite:///outputs/mlflow.db"

    moved = composed("logger=mlflow", "paths.root=/somewhere", hydra=True)
    assert moved.hydra.run.dir.startswith("/somewhere/runs/")
    assert moved.hydra.sweep.dir.startswith("/somewhere/multirun/")
    assert moved.data.cache_dir == "/somewhere/.cache"
    assert moved.logger.mlflow.tracking_uri == "sqlite:////somewhere/mlflow.db"
    assert composed("paths.root=/somewhere", "resume=/a/run", hydra=True).hydra.run.dir == "/a/run"

    evals = composed("run=/a/run", "paths.root=/somewhere", config="eval", hydra=True)
    assert evals.hydra.run.dir.startswith("/somewhere/evals/") and evals.data.cache_dir == "/somewhere/.cache"

    monkeypatch.setenv("HYBRID_SYSID_CACHE", "/the/cache")  # the environment still names the cache, as before
    assert composed("paths.root=/somewhere").data.cache_dir == "/the/cache"


def test_debug_overfit_fits_one_batch(tmp_path):
    import pandas as pd

    from hybrid_sysid.training.run import train

    cfg = composed("debug=overfit", f"data.cache_dir={tmp_path / 'cache'}", "logger=csv", "trainer.progress_bar=false")
    record = train(cfg, tmp_path / "run")
    assert record["status"] == "completed" and record["steps"] == cfg.trainer.max_steps
    loss = pd.read_csv(tmp_path / "run" / "csv" / "metrics.csv")["train/loss"].dropna().to_numpy()
    assert len(loss) >= 5 and loss[-1] < loss[0] / 10  # the same batch, again and again: its loss collapses


def test_debug_profiler_writes_its_report_into_the_run_directory(tmp_path):
    from hybrid_sysid.training.run import train

    cfg = composed("debug=profiler", f"data.cache_dir={tmp_path / 'cache'}", "trainer.progress_bar=false")
    assert train(cfg, tmp_path / "run")["status"] == "completed"
    report = (tmp_path / "run" / "fit-profiler.txt").read_text()
    assert "FIT Profiler Report" in report and "run_training_batch" in report


def test_a_run_saved_before_these_groups_still_resumes(tmp_path):
    """A run directory written before callbacks, paths and trainer.profiler existed holds none of them: resuming
    it with today's defaults (or another paths.root, or a profiler) is the same run."""
    import yaml
    from omegaconf import OmegaConf

    from hybrid_sysid.runs.resume import check_resume
    from hybrid_sysid.runs.rundir import RunDir

    cfg = composed("data=tiny", "trainer=debug")
    old = OmegaConf.to_container(cfg, resolve=False)
    del old["callbacks"], old["paths"], old["trainer"]["profiler"]
    old["data"]["cache_dir"] = "${oc.env:HYBRID_SYSID_CACHE,outputs/.cache}"
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra" / "config.yaml").write_text(yaml.safe_dump(old))
    for extra in ([], ["paths.root=/elsewhere", "trainer.profiler=simple"]):
        check_resume(RunDir(tmp_path), composed("data=tiny", "trainer=debug", *extra))
    with pytest.raises(ConfigError, match=r"is not allowed: .* \(callbacks\.early_stopping\._target_, "):  # stops
        check_resume(RunDir(tmp_path), composed("data=tiny", "trainer=debug", "callbacks=early_stopping"))
