"""Experiment trackers (conf/logger): each writes the files a user opens, holding the run's config, training
loss, validation metrics, learning-curve rows and final results, the same numbers as the run's own record; and
the names, tags, artifacts and TensorBoard hparams a user sees, read back from the stores."""

import importlib.util
import subprocess
from pathlib import Path

import pandas as pd
import pytest
import yaml
from hydra.types import RunMode
from omegaconf import OmegaConf

from hybrid_sysid.config import ConfigError, validate
from hybrid_sysid.training import tracking
from hybrid_sysid.training.run import train
from hybrid_sysid.training.tracking import Naming, job_naming

from helpers.app_process import run_app

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
    # 60 steps: the module logs the loss every 50th step; Lightning logs again at the stop that ValidateAtEnd asks
    # for at the last step (the latest value, repeated)
    assert len(series["train/loss"]) == 2 and series["train/loss"][0] == pytest.approx(series["train/loss"][1])
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
        match=r"^logger.mlflow is not allowed: it needs the mlflow package, not installed: "
        r'pip install -e "\.\[loggers\]"$',
    ):
        validate(cfg)


def test_an_mlflow_server_that_does_not_answer_is_one_line_before_any_work(make_cfg):
    """MLflow would retry a closed port for minutes, then fail the run with a traceback; validate asks the port
    first. A port just closed answers nothing; one listening passes; the password never shows."""
    import socket

    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        port = listening.getsockname()[1]
        validate(make_cfg("data=tiny", "logger=mlflow", f"logger.mlflow.tracking_uri=http://127.0.0.1:{port}"))
    uri = f"http://user:secret@127.0.0.1:{port}"
    with pytest.raises(
        ConfigError, match=r"^logger.mlflow.tracking_uri = http://user:\*\*\*@127.0.0.1:\d+ is not a"
    ) as e:
        validate(make_cfg("data=tiny", "logger=mlflow", f"logger.mlflow.tracking_uri={uri}"))
    assert "no server answers" in str(e.value) and "secret" not in str(e.value)


def test_an_sqlite_store_that_is_no_database_is_one_line_before_any_work(make_cfg, tmp_path):
    """A text file or a folder as the SQLite store is refused before the run (it was an 86-line SQLAlchemy
    traceback and a failed run); a store MLflow made, an empty file and a file not yet there pass."""
    import sqlite3

    def check(path):
        validate(make_cfg("data=tiny", "logger=mlflow", f"logger.mlflow.tracking_uri=sqlite:///{path}"))

    (tmp_path / "notes.db").write_text("not a database\n")
    (tmp_path / "folder.db").mkdir()
    for path, why in ((tmp_path / "notes.db", "holds something else"), (tmp_path / "folder.db", "no regular file")):
        with pytest.raises(ConfigError, match=rf"^logger.mlflow.tracking_uri = sqlite:///.* is not allowed: .*{why}"):
            check(path)
    sqlite3.connect(tmp_path / "real.db").execute("create table t (x)").connection.commit()
    (tmp_path / "empty.db").touch()
    for name in ("real.db", "empty.db", "new.db"):
        check(tmp_path / name)


def test_a_search_or_launcher_without_its_plugin_names_the_extra(monkeypatch):
    from hybrid_sysid.launch import process as app

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


def fake_hydra(sweep_dir, overrides, params=None, mode=RunMode.MULTIRUN, preset="robustness", num=3):
    """What a job's HydraConfig.get() holds of its names."""
    return OmegaConf.create(
        {
            "mode": mode,
            "runtime": {"choices": {"experiment": preset, "objective": "hybrid", "model": "fast_cnn"}},
            "overrides": {"task": overrides},
            "sweep": {"dir": str(sweep_dir)},
            "sweeper": {"params": params},
            "job": {"num": num},
        }
    )


def test_a_sweep_s_runs_are_named_by_the_overrides_that_differ(tmp_path):
    sweep = tmp_path / "2026-11-24_01-02-03_000001"
    sweep.mkdir()
    job = ["data=tiny", "logger=mlflow", "objective=hybrid", "seed=1"]
    naming = job_naming(fake_hydra(sweep, job, {"seed": "0,1,2"}))  # no multirun.yaml: the sweeper's keys only
    assert naming.run == "seed=1" and naming.varied == ("seed=1",)
    assert naming.experiment == "robustness:2026-11-24_01-02-03_000001" and naming.sweep_dir == sweep
    # the command line's sweeps, as Hydra saved them in multirun.yaml before the first job
    saved = {"hydra": {"overrides": {"task": ["data=tiny", "logger=mlflow", "objective=labelled,hybrid"]}}}
    OmegaConf.save(
        OmegaConf.create({**saved, "hydra": {**saved["hydra"], "sweeper": {"params": {"seed": "range(3)"}}}}),
        sweep / "multirun.yaml",
    )
    naming = job_naming(fake_hydra(sweep, job, {"seed": "range(3)"}))
    assert naming.run == "objective=hybrid seed=1" and naming.preset == "robustness"
    assert job_naming(fake_hydra(sweep, job, preset=None)).experiment == "sweep:2026-11-24_01-02-03_000001"
    # a single run: its overrides (the logger's left out), in the experiment "runs"
    single = job_naming(fake_hydra(sweep, job, mode=RunMode.RUN))
    assert (single.experiment, single.run, single.sweep_dir) == ("runs", "data=tiny objective=hybrid seed=1", None)
    assert job_naming(fake_hydra(sweep, ["logger=mlflow"], mode=RunMode.RUN)).run is None  # its directory's name
    assert tracking.swept_keys(sweep, {"model.optim.lr": "tag(log, interval(0.002, 0.05))"}) == {"objective", "seed"}
    assert tracking.swept_keys(tmp_path / "none", {"model.optim.lr": "tag(log, interval(0.002, 0.05))"}) == {
        "model.optim.lr"
    }


def git_head():
    here = Path(tracking.__file__).parent
    out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True)
    return out.stdout.strip() if out.returncode == 0 else None


def sweep_naming(sweep_dir, seed, objective="labelled"):
    varied = (f"objective={objective}", f"seed={seed}")
    return Naming(
        f"robustness:{sweep_dir.name}",
        " ".join(varied),
        varied,
        "robustness",
        sweep_dir,
        {"experiment": "robustness", "objective": objective, "model": "fast_cnn"},
    )


def test_mlflow_names_tags_and_artifacts(make_cfg, tmp_path, capfd, caplog):
    pytest.importorskip("mlflow", reason='needs the loggers extra: pip install -e ".[loggers]"')
    from mlflow import MlflowClient

    uri = f"sqlite:///{tmp_path / 'outputs' / 'mlflow.db'}"
    sweep = tmp_path / "sw"
    for seed in (0, 1):
        cfg = make_cfg(*TINY, "logger=mlflow", f"logger.mlflow.tracking_uri={uri}", f"seed={seed}")
        hydra_dir = sweep / str(seed) / ".hydra"  # as Hydra writes it before the job
        hydra_dir.mkdir(parents=True)
        OmegaConf.save(cfg, hydra_dir / "config.yaml")
        (hydra_dir / "overrides.yaml").write_text(f"- seed={seed}\n")
        train(cfg, sweep / str(seed), [f"seed={seed}"], experiment=sweep_naming(sweep, seed))
    client = MlflowClient(uri)
    exp = client.get_experiment_by_name("robustness:sw")
    assert exp.tags["preset"] == "robustness" and exp.tags["sweep"] == "sw"
    assert exp.artifact_location == (tmp_path / "outputs" / "mlartifacts" / "robustness:sw").as_uri()
    runs = {r.info.run_name: r for r in client.search_runs([exp.experiment_id])}
    assert sorted(runs) == ["objective=labelled seed=0", "objective=labelled seed=1"]
    head = git_head()
    for seed in (0, 1):
        run = runs[f"objective=labelled seed={seed}"]
        tags = run.data.tags
        assert (tags["objective"], tags["seed"], tags["preset"], tags["sweep"]) == (
            "labelled",
            str(seed),
            "robustness",
            "sw",
        )
        assert tags["run_dir"] == str((sweep / str(seed)).resolve()) and tags["overrides"] == f"seed={seed}"
        assert tags.get("git_commit") == head and tags.get("mlflow.source.git.commit") == head
        files = {a.path for a in client.list_artifacts(run.info.run_id)}
        assert {"metrics.json", "curves.csv", "config"} <= files
        config = {a.path for a in client.list_artifacts(run.info.run_id, "config")}
        assert config == {"config/config.yaml", "config/overrides.yaml"}
    # the figures, drawn after the run: added to the run this process finished there
    figures = sweep / "0" / "figures"
    figures.mkdir()
    (figures / "learning_curves.png").write_bytes(b"\x89PNG\r\n")
    tracking.log_run_figures(sweep / "0")
    run_id = runs["objective=labelled seed=0"].info.run_id
    assert [a.path for a in client.list_artifacts(run_id, "figures")] == ["figures/learning_curves.png"]
    # the sweep's end: its summary and figures in the run "sweep summary", the table as the experiment's note
    (sweep / "summary.md").write_text("| objective | p1 |\n| --- | --- |\n| labelled | 1.0 |\n")
    (sweep / "summary.csv").write_text("objective,p1\nlabelled,1.0\n")
    (sweep / "figures").mkdir()
    (sweep / "figures" / "robustness.png").write_bytes(b"\x89PNG\r\n")
    config = OmegaConf.create(
        {"logger": OmegaConf.to_container(cfg.logger), "hydra": {"runtime": {"choices": {"experiment": "robustness"}}}}
    )
    for _ in range(2):  # a re-run sweep logs into the same run
        tracking.log_sweep(config, sweep)
    summary = client.search_runs([exp.experiment_id], "tags.kind = 'sweep'")
    assert [r.info.run_name for r in summary] == [tracking.SWEEP_RUN] and summary[0].info.status == "FINISHED"
    files = {a.path for a in client.list_artifacts(summary[0].info.run_id)}
    assert {"summary.md", "summary.csv", "figures"} <= files
    assert client.get_experiment(exp.experiment_id).tags["mlflow.note.content"].startswith("| objective")
    said = capfd.readouterr()
    for text in (said.out, said.err, caplog.text):
        assert "not found. Creating it" not in text and "not written to the tracker" not in text


def test_tensorboard_hparams_hold_the_hyperparameters_and_final_metrics(make_cfg, tmp_path):
    pytest.importorskip("tensorboard", reason='needs the loggers extra: pip install -e ".[loggers]"')
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    from tensorboard.plugins.hparams import metadata

    sweep = tmp_path / "sw"
    record = train(make_cfg(*TINY, "logger=tensorboard"), sweep / "0", experiment=sweep_naming(sweep, 0))
    logdir = sweep / "tensorboard" / "objective=labelled seed=0"  # the UI's run name: the differing overrides
    assert [p.name for p in (sweep / "tensorboard").iterdir()] == [logdir.name]
    events = EventAccumulator(str(logdir)).Reload()
    content = events.PluginTagToContent(metadata.PLUGIN_NAME)
    start = metadata.parse_session_start_info_plugin_data(content[metadata.SESSION_START_INFO_TAG])
    hparams = {k: v.WhichOneof("kind") and getattr(v, v.WhichOneof("kind")) for k, v in start.hparams.items()}
    assert hparams["objective"] == "labelled" and hparams["model"] == "fast_cnn" and hparams["seed"] == 0
    assert hparams["model.optim.lr"] == pytest.approx(0.02) and hparams["noise.train_std"] == 0
    assert hparams["trainer.max_steps"] == 60
    experiment = metadata.parse_experiment_plugin_data(content[metadata.EXPERIMENT_TAG])
    shown = {m.name.tag for m in experiment.metric_infos}
    final = {k: v for k, v in final_metrics(record).items() if k.startswith("final/test/")}
    assert shown == set(final) and {k.rsplit("/", 1)[-1] for k in shown} == {"p1_mean_rel_dev", "p2_mean_rel_dev"}
    assert {h.name for h in experiment.hparam_infos} == set(hparams)
    assert {h.name for h in experiment.hparam_infos if h.differs} == {"objective", "seed"}  # the tab shows them first
    scalars = {t: [e.value for e in events.Scalars(t)] for t in events.Tags()["scalars"]}
    for tag, value in final.items():  # the table's cells: the metrics' logged values
        assert scalars[tag] == pytest.approx([value])


@pytest.mark.slow  # end to end; by default names, tags, artifacts, sweep run and hparams are checked in process
def test_a_tracked_sweep_as_a_user_runs_it(tmp_path, tiny_cache):
    """A 2-job sweep in a new process with both trackers: names, figures, the summary run, and no warning."""
    pytest.importorskip("mlflow", reason='needs the loggers extra: pip install -e ".[loggers]"')
    pytest.importorskip("tensorboard", reason='needs the loggers extra: pip install -e ".[loggers]"')
    from mlflow import MlflowClient

    args = ["-m", "objective=labelled,hybrid", "data=tiny", "trainer=debug", "trainer.progress_bar=false"]
    args += ["logger=[mlflow,tensorboard]", f"paths.root={tmp_path / 'outputs'}", f"hydra.sweep.dir={tmp_path / 'sw'}"]
    args += ["run_figures=true"]  # a sweep's jobs draw none by default
    proc = run_app(tmp_path, *args, cache=tiny_cache)
    assert proc.returncode == 0, proc.stderr[-3000:]
    client = MlflowClient(f"sqlite:///{tmp_path / 'outputs' / 'mlflow.db'}")
    exp = client.get_experiment_by_name("sweep:sw")
    runs = {r.info.run_name: r for r in client.search_runs([exp.experiment_id])}
    assert sorted(runs) == ["objective=hybrid", "objective=labelled", tracking.SWEEP_RUN]
    for name in ("objective=hybrid", "objective=labelled"):
        assert runs[name].data.tags["objective"] == name.removeprefix("objective=")
        figures = {a.path for a in client.list_artifacts(runs[name].info.run_id, "figures")}
        assert figures == {"figures/learning_curves.png", "figures/test_predictions.png"}
    files = {a.path for a in client.list_artifacts(runs[tracking.SWEEP_RUN].info.run_id)}
    assert {"summary.md", "summary.csv", "multirun.yaml"} <= files
    assert sorted(p.name for p in (tmp_path / "sw" / "tensorboard").iterdir()) == [
        "objective=hybrid",
        "objective=labelled",
    ]
    said = proc.stdout + proc.stderr + "".join(p.read_text() for p in (tmp_path / "sw").glob("*/*.log"))
    assert "not found. Creating it" not in said and "not written to the tracker" not in said
    assert not (tmp_path / "mlruns").exists()  # the artifacts beside the store, not in the working directory
