"""Experiment trackers (conf/logger): each writes the files a user opens, holding the run's config, training
loss, validation metrics, learning-curve rows and final results, the same numbers as the run's own record."""

import importlib.util

import pandas as pd
import pytest
import yaml

from hybrid_sysid.config import ConfigError, validate
from hybrid_sysid.training.run import train

TINY = ["data=tiny", "trainer=debug", "trainer.max_steps=60", "trainer.eval_every_n_steps=30"]


def final_metrics(record) -> dict:
    return {
        f"final/{r['split']}/noise_{r['noise_std']:g}/K{r['windows']}/{r['parameter']}_mean_rel_dev": r["mean_rel_dev"]
        for r in record["results"]
    }


def curve_series(run_dir) -> dict:
    """name -> the run's curves.csv values of that learning-curve row, in step order."""
    c = pd.read_csv(run_dir / "curves.csv").sort_values("step")
    names = [f"curve/{r.split}/noise_{r.noise_std:g}/{r.parameter}_mean_rel_dev" for r in c.itertuples()]
    return c.assign(name=names).groupby("name").mean_rel_dev.apply(list).to_dict()


def check_logged(series: dict, record: dict, run_dir) -> None:
    """series: metric name -> its logged values in step order, as a tracker shows them; checked against the
    run's record and curves.csv."""
    assert len(series["train/loss"]) == 1  # 60 steps: the module logs the loss every 50th step
    assert len(series["val/loss"]) == 2 and len(series["val/rel_dev"]) == 2  # a validation every 30 steps
    assert min(series[record["monitor"]]) == pytest.approx(record["best_score"])  # the selected checkpoint
    for name, values in curve_series(run_dir).items():
        assert series[name] == pytest.approx(values)
    for name, value in final_metrics(record).items():
        assert series[name] == pytest.approx([value])


def test_csv_logger_writes_metrics_and_hparams(make_cfg, tmp_path):
    cfg = make_cfg(*TINY, "logger=csv")
    record = train(cfg, tmp_path / "run")
    metrics = pd.read_csv(tmp_path / "run" / "csv" / "metrics.csv")
    check_logged({c: metrics[c].dropna().tolist() for c in metrics.columns}, record, tmp_path / "run")
    hparams = yaml.safe_load((tmp_path / "run" / "csv" / "hparams.yaml").read_text())
    assert hparams["model.optim.lr"] == cfg.model.optim.lr and hparams["trainer.max_steps"] == 60
    assert hparams["objective._target_"].endswith("LabelledObjective")


def test_tensorboard_logger_writes_event_files(make_cfg, tmp_path):
    pytest.importorskip("tensorboard", reason='needs the loggers extra: pip install -e ".[loggers]"')
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    record = train(make_cfg(*TINY, "logger=tensorboard"), tmp_path / "run")
    events = EventAccumulator(str(tmp_path / "run" / "tensorboard")).Reload()
    series = {
        tag: [e.value for e in sorted(events.Scalars(tag), key=lambda e: e.step)] for tag in events.Tags()["scalars"]
    }
    check_logged(series, record, tmp_path / "run")


def test_mlflow_logger_groups_a_sweep_s_jobs_in_one_experiment(make_cfg, tmp_path):
    pytest.importorskip("mlflow", reason='needs the loggers extra: pip install -e ".[loggers]"')
    from mlflow import MlflowClient

    uri = f"sqlite:///{tmp_path / 'outputs' / 'mlflow.db'}"
    records = {
        seed: train(
            make_cfg(*TINY, "logger=mlflow", f"logger.mlflow.tracking_uri={uri}", f"seed={seed}"),
            tmp_path / str(seed),
            experiment="sweep-a",
            run_name=f"seed={seed}",
        )
        for seed in (0, 1)
    }
    client = MlflowClient(uri)
    runs = client.search_runs([client.get_experiment_by_name("sweep-a").experiment_id])
    assert sorted(r.info.run_name for r in runs) == ["seed=0", "seed=1"]
    for run in runs:
        seed = int(run.info.run_name.removeprefix("seed="))
        assert run.info.status == "FINISHED" and run.data.params["seed"] == str(seed)
        assert float(run.data.params["model.optim.lr"]) == 0.02
        series = {
            name: [m.value for m in sorted(client.get_metric_history(run.info.run_id, name), key=lambda m: m.step)]
            for name in run.data.metrics
        }
        check_logged(series, records[seed], tmp_path / str(seed))


def test_a_logger_without_its_library_is_a_one_line_error(make_cfg, monkeypatch):
    cfg = make_cfg("data=tiny", "logger=mlflow")
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "mlflow" else real(name, *a))
    with pytest.raises(
        ConfigError,
        match=r"^logger.mlflow needs the mlflow package, which is not installed: "
        r'pip install -e "\.\[loggers\]"$',
    ):
        validate(cfg)


def test_a_search_or_launcher_without_its_plugin_names_the_extra(monkeypatch):
    from hybrid_sysid.cli import job as app

    monkeypatch.setattr(app, "installed", lambda module: False)
    assert (
        app.missing_extra(["seed=1", "hparams_search=fast_cnn"])
        == 'hparams_search=fast_cnn needs optuna, which is not installed: pip install -e ".[search]"'
    )
    assert 'pip install -e ".[slurm]"' in app.missing_extra(["launcher=slurm"])
    assert (
        app.missing_extra(["experiment=tuned"])
        == 'experiment=tuned needs optuna, which is not installed: pip install -e ".[search]"'
    )
    monkeypatch.setattr(app, "installed", lambda module: True)
    assert app.missing_extra(["hparams_search=fast_cnn", "launcher=slurm"]) is None
