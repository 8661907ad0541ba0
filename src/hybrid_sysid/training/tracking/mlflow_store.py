"""What a run and a sweep keep in MLflow beyond Lightning's metrics: tags (objective, seed, preset, sweep, run
directory, overrides, git commit, the config's ``tags``), the run's files (its record, curves and Hydra config;
its figures once drawn, :func:`log_run_figures`), and a sweep's summary table and figures in one more run of its
experiment, ``sweep summary`` (:func:`log_sweep`), the table also as the experiment's description. Nothing here
fails a run that has written its record: what cannot be written is a warning."""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path
from typing import Sequence

from filelock import FileLock
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config.tags import joined
from hybrid_sysid.runs.layout import FIGURES, SWEEP_CONFIG, TRACKED
from hybrid_sysid.runs.provenance import git_state
from hybrid_sysid.training.tracking.naming import Naming, experiment_name, objective_name

log = logging.getLogger("hybrid_sysid")
SWEEP_RUN = "sweep summary"  # the MLflow run holding a sweep's summary table and figures
RUN_NAME = "mlflow.runName"  # the tag MLflow shows as a run's name (mlflow.utils.mlflow_tags.MLFLOW_RUN_NAME)
SWEEP_ARTIFACTS = ("*.md", "*.csv", "*.tex", SWEEP_CONFIG, "optimization_results.yaml")
_finished: dict[str, list[tuple[str, str]]] = {}  # run directory -> (tracking URI, MLflow run id) of its runs


def mlflow_client(uri: str | None):
    """MLflow's client of the tracking store ``uri`` (MLflow's default where None); mlflow is an optional extra."""
    from mlflow import MlflowClient  # deferred

    return MlflowClient(uri)


def kind(lg) -> str:
    """A logger node's class name: MLFlowLogger, TensorBoardLogger, CSVLogger."""
    return str(lg.get("_target_", "")).rsplit(".", 1)[-1]


def run_tags(cfg: DictConfig, naming: Naming, run_dir: Path, overrides: Sequence[str] = ()) -> dict[str, str]:
    """The MLflow tags of a job's run (module docstring); the git ones only from a git checkout."""
    tags = {
        "objective": objective_name(cfg, naming.choices),
        "seed": str(cfg.seed),
        "run_dir": str(Path(run_dir).resolve()),
        "overrides": " ".join(overrides),
    }
    if cfg.get("tags"):  # the user's labels, one field: search them with tags.tags LIKE '%dt2ms%'
        tags["tags"] = joined(cfg.tags)
    if cfg.get("baseline") is not None:
        tags["baseline"] = tags["objective"]
    if naming.choices.get("model") and cfg.get("baseline") is None:
        tags["model"] = str(naming.choices["model"])
    tags.update(sweep_tags(naming.preset, naming.sweep_dir))
    return tags


def sweep_tags(preset: str | None, sweep_dir: Path | None) -> dict[str, str]:
    tags = {}
    if preset:
        tags["preset"] = str(preset)
    if sweep_dir is not None:
        tags["sweep"], tags["sweep_dir"] = Path(sweep_dir).name, str(Path(sweep_dir).resolve())
    state = git_state()
    if state is not None:
        # mlflow.source.git.commit: the commit the MLflow UI shows on the run's page
        tags["git_commit"] = tags["mlflow.source.git.commit"] = state[0]
        tags["git_dirty"] = str(state[1]).lower()
    return tags


def artifact_root(db: Path, experiment: str) -> str:
    """The artifact location of an experiment in a SQLite store: ``<its folder>/mlartifacts/<experiment>``, not
    MLflow's default ``./mlruns`` in whatever directory the command ran from."""
    return (db.resolve().parent / "mlartifacts" / experiment.replace("/", "_").replace("..", "_")).as_uri()


def mlflow_experiment(client, name: str, artifact_location: str | None = None, tags: dict | None = None) -> str:
    """The id of the MLflow experiment ``name``, created (or restored from the bin) if needed, with ``tags``:
    created here, so Lightning finds it and prints no "not found. Creating it." warning."""
    found = client.get_experiment_by_name(name)
    if found is None:
        try:
            exp_id = client.create_experiment(name, artifact_location=artifact_location)
        except Exception:  # noqa: BLE001 - another process (a server store, no lock) created it meanwhile
            found = client.get_experiment_by_name(name)
            if found is None:
                raise
            exp_id = found.experiment_id
    else:
        exp_id = found.experiment_id
        if found.lifecycle_stage == "deleted":
            client.restore_experiment(exp_id)
    for key, value in (tags or {}).items():
        if key.startswith("git") or key.startswith("mlflow."):
            continue  # a run's, not the experiment's
        client.set_experiment_tag(exp_id, key, value)
    return exp_id


def guarded(what: str, fn, *args) -> None:
    try:
        fn(*args)
    except Exception as exc:  # noqa: BLE001 - the record holds every number: a tracker's extra is a warning
        log.warning("%s not written to the tracker: %s: %s", what, type(exc).__name__, exc)


def finished(run_dir, tracking_uri: str, run_id: str) -> None:
    """Remember the MLflow run a run directory's logger finished, for its figures drawn later."""
    _finished.setdefault(str(Path(run_dir).resolve()), []).append((tracking_uri, run_id))


def log_run_files(client, run_id: str, run_dir: Path, figures_only: bool = False) -> None:
    run_dir = Path(run_dir)
    if not figures_only:
        for rel, artifact_path in TRACKED.items():
            if (run_dir / rel).is_file():
                client.log_artifact(run_id, str(run_dir / rel), artifact_path or None)
    for png in sorted((run_dir / FIGURES).glob("*.png")):
        client.log_artifact(run_id, str(png), "figures")


def log_run_figures(run_dir: Path) -> None:
    """Add the run's figures (``<run dir>/figures/*.png``, drawn after the run ended) to the MLflow runs this
    process finished in ``run_dir``; nothing without such a run. A failure is a warning."""
    for uri, run_id in _finished.pop(str(Path(run_dir).resolve()), []):
        guarded("the run's figures", log_run_files, mlflow_client(uri), run_id, run_dir, True)


def log_sweep(config: DictConfig, sweep_dir: Path) -> None:
    """At a sweep's end (hybrid_sysid.launch.sweep), for each MLflow logger of the sweep's config: its
    summary table (summary.md, .csv, ...), figures and multirun.yaml as artifacts of the experiment's run
    ``sweep summary``, and summary.md as the experiment's description. A failure is a warning."""
    for lg in (OmegaConf.select(config, "logger", default=None) or {}).values():
        if kind(lg) == "MLFlowLogger":
            guarded("the sweep's summary", _log_sweep, config, lg, Path(sweep_dir))


def _log_sweep(config: DictConfig, lg: DictConfig, sweep_dir: Path) -> None:
    preset = OmegaConf.select(config, "hydra.runtime.choices.experiment", default=None)
    name = str(lg.experiment_name) if lg.get("experiment_name") is not None else experiment_name(preset, sweep_dir)
    uri, location = str(lg.tracking_uri), lg.get("artifact_location")
    lock = contextlib.nullcontext()
    if uri.startswith("sqlite:///"):
        db = Path(uri.removeprefix("sqlite:///"))
        location = location or artifact_root(db, name)
        lock = FileLock(str(db) + ".lock")
    client, tags = mlflow_client(uri), sweep_tags(preset, sweep_dir)
    with lock:
        exp_id = mlflow_experiment(client, name, location, tags)
    previous = client.search_runs([exp_id], filter_string="tags.kind = 'sweep'", max_results=1)
    if previous:  # a re-run sweep: the same run, its files replaced
        run_id = previous[0].info.run_id
    else:
        run_id = client.create_run(exp_id, tags={RUN_NAME: SWEEP_RUN, "kind": "sweep", **tags}).info.run_id
    for pattern in SWEEP_ARTIFACTS:
        for path in sorted(sweep_dir.glob(pattern)):
            client.log_artifact(run_id, str(path))
    for path in sorted((sweep_dir / FIGURES).glob("*")):
        if path.suffix in (".png", ".pdf", ".svg"):
            client.log_artifact(run_id, str(path), "figures")
    summary = sweep_dir / "summary.md"
    if summary.is_file():
        client.set_experiment_tag(exp_id, "mlflow.note.content", summary.read_text(encoding="utf-8"))
    client.set_terminated(run_id, "FINISHED")
