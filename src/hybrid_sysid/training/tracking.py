"""Experiment trackers (conf/logger): Lightning loggers for a run, and what the run logs to them beyond
Lightning's own training loss and validation metrics: the resolved config as hyperparameters, the
learning-curve rows, the final results, and (docs/usage.md#experiment-trackers):

- names: a sweep is one MLflow experiment, ``<preset>:<sweep directory's name>`` (``sweep:<name>`` without an
  experiment preset); its jobs are runs named by the overrides that differ between them (``objective=hybrid
  seed=1``: the sweep's swept keys, :func:`swept_keys`). A single run goes to the experiment ``runs``, named by
  its overrides (the logger's left out) or else its directory's name. TensorBoard names a run by its directory:
  a sweep's jobs write to ``<sweep dir>/tensorboard/<run name>/`` (``tensorboard --logdir <sweep
  dir>/tensorboard``), a single run to ``<run dir>/tensorboard/``.
- MLflow: tags (objective, seed, preset, sweep, run directory, overrides, git commit) and artifacts (metrics.json,
  curves.csv, the run's Hydra config; its figures once drawn, :func:`log_run_figures`; the best and last
  checkpoints only with ``logger.mlflow.log_model=true``). The sweep's summary table and figures go to one more
  run of the experiment, ``sweep summary`` (:func:`log_sweep`), and the table also to the experiment's
  description.
- TensorBoard: the HPARAMS tab's table (:func:`hparams_values` with the final test metrics).

Nothing here fails a run that has written its record: a tracker's artifact or tag that cannot be written is a
warning.
"""

from __future__ import annotations

import contextlib
import logging
import subprocess
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Iterable, Sequence

from filelock import FileLock
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import flatten
from hybrid_sysid.config.targets import build

log = logging.getLogger("hybrid_sysid")

SINGLE_RUNS = "runs"  # the MLflow experiment of runs outside a sweep
NO_PRESET = "sweep"  # the first part of the experiment name of a sweep without experiment=<preset>
SWEEP_RUN = "sweep summary"  # the MLflow run holding a sweep's summary table and figures
MAX_NAME = 200  # characters of a run name (MLflow and file names both take it)
# the hyperparameters of TensorBoard's HPARAMS table, beside the config groups chosen and the swept keys
HPARAM_GROUPS = ("objective", "baseline", "model", "data", "noise")
HPARAM_KEYS = ("seed", "model.optim.lr", "model.batch_size", "noise.train_std", "trainer.max_steps")
RUN_ARTIFACTS = {  # a run's file -> its folder among the MLflow run's artifacts
    "metrics.json": "",
    "curves.csv": "",
    ".hydra/config.yaml": "config",
    ".hydra/overrides.yaml": "config",
    ".hydra/hydra.yaml": "config",
}
SWEEP_ARTIFACTS = ("*.md", "*.csv", "*.tex", "multirun.yaml", "optimization_results.yaml")
_finished: dict[str, list[tuple[str, str]]] = {}  # run directory -> (tracking URI, MLflow run id) of its runs


@dataclass(frozen=True)
class Naming:
    """How a job is named in the trackers: its experiment, its run name, the overrides that differ between the
    sweep's jobs (``varied``), the experiment preset, the sweep directory and Hydra's config-group choices."""

    experiment: str = SINGLE_RUNS
    run: str | None = None
    varied: tuple[str, ...] = ()
    preset: str | None = None
    sweep_dir: Path | None = None
    choices: dict = field(default_factory=dict)


def experiment_name(preset: str | None, sweep_dir: Path) -> str:
    """A sweep's experiment: ``<preset>:<sweep directory's name>``, e.g. ``robustness:2026-11-24_01-02-03_123456``
    (not "/": MLflow's UI takes a name with a slash for a folder path and shows only its last part)."""
    return f"{preset or NO_PRESET}:{Path(sweep_dir).name}"


def job_naming(hc: DictConfig) -> Naming:
    """The naming of the job whose Hydra config (``HydraConfig.get()``) is ``hc``; a sweep's job, when its
    naming cannot be told, is named after its number (never an error: the job must run)."""
    try:
        return _job_naming(hc)
    except Exception as exc:  # noqa: BLE001
        log.warning("tracker names not found (%s: %s): the run is named after its number", type(exc).__name__, exc)
        num = OmegaConf.select(hc, "job.num", default=None)
        return Naming(SINGLE_RUNS, None if num is None else f"job {num}")


def _job_naming(hc: DictConfig) -> Naming:
    from hydra.types import RunMode

    choices = {k: v for k, v in OmegaConf.to_container(hc.runtime.choices).items() if v is not None}
    preset, overrides = choices.get("experiment"), list(hc.overrides.task)
    if hc.mode != RunMode.MULTIRUN:
        shown = [o for o in overrides if _key(o).split(".")[0] != "logger"]
        return Naming(SINGLE_RUNS, _clip(" ".join(shown)) or None, (), preset, None, choices)
    sweep_dir = Path(str(hc.sweep.dir))
    swept = swept_keys(sweep_dir, hc.sweeper.get("params"))
    varied = tuple(o for o in overrides if _key(o) in swept)
    run = _clip(" ".join(varied)) or f"job {hc.job.num}"
    return Naming(experiment_name(preset, sweep_dir), run, varied, preset, sweep_dir, choices)


def swept_keys(sweep_dir: Path, params=None) -> set[str]:
    """The keys a sweep varies: its command-line sweeps (``objective=labelled,hybrid``, ``seed=range(3)``) and its
    sweeper's parameters (an experiment preset's ``hydra.sweeper.params``, a search's space), read from the
    sweep's multirun.yaml, which Hydra's sweepers write before the first job; ``params``: the job's own sweeper
    parameters, for a sweep directory without that file."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    texts = []
    try:
        saved = OmegaConf.load(Path(sweep_dir) / "multirun.yaml")
        texts += [str(o) for o in saved.hydra.overrides.task]
        params = saved.hydra.sweeper.get("params", params)
    except Exception:  # noqa: BLE001 - no readable file: the sweeper's parameters alone
        pass
    if params:
        given = OmegaConf.to_container(params) if OmegaConf.is_config(params) else dict(params)
        texts += [f"{k}={v}" for k, v in given.items() if v is not None]
    parser, keys = OverridesParser.create(), set()
    for text in texts:
        try:
            override = parser.parse_override(text)
        except Exception:  # noqa: BLE001 - Hydra refused it already, or will: it names no swept key here
            continue
        if override.is_sweep_override():
            keys.add(_key(text))
    return keys


def _key(override: str) -> str:
    """The key an override sets: ``+model.optim.lr=0.1`` -> ``model.optim.lr``, ``db@pkg=x`` -> ``db@pkg``."""
    return override.split("=", 1)[0].lstrip("+~")


def _clip(name: str) -> str:
    return name if len(name) <= MAX_NAME else name[: MAX_NAME - 1] + "…"


@lru_cache(maxsize=1)
def git_state() -> tuple[str, bool] | None:
    """(commit, whether tracked files differ from it) of the git checkout this code runs from; None outside a
    checkout, without git, or when git does not answer within seconds."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        commit = head.stdout.strip()
        if head.returncode != 0 or len(commit) != 40:
            return None
        diff = subprocess.run(["git", "diff", "--quiet", "HEAD", "--"], cwd=here, capture_output=True, timeout=10)
        return commit, diff.returncode != 0
    except Exception:  # noqa: BLE001 - no git, a timeout, ...: the run is tracked without its commit
        return None


def _objective(cfg: DictConfig, choices: dict) -> str:
    """The objective's config-group name (a baseline's name for a baseline run); outside Hydra, from its class:
    HybridObjective -> hybrid."""
    if cfg.get("baseline") is not None:
        return str(choices.get("baseline") or str(cfg.baseline._target_).rsplit(".", 1)[-1])
    if "objective" in choices:
        return str(choices["objective"])
    name = str(cfg.objective._target_).rsplit(".", 1)[-1]
    return name.removesuffix("Objective").lower() or name


def run_tags(cfg: DictConfig, naming: Naming, run_dir: Path, overrides: Sequence[str] = ()) -> dict[str, str]:
    """The MLflow tags of a job's run (module docstring); the git ones only from a git checkout."""
    tags = {
        "objective": _objective(cfg, naming.choices),
        "seed": str(cfg.seed),
        "run_dir": str(Path(run_dir).resolve()),
        "overrides": " ".join(overrides),
    }
    if cfg.get("baseline") is not None:
        tags["baseline"] = tags["objective"]
    if naming.choices.get("model") and cfg.get("baseline") is None:
        tags["model"] = str(naming.choices["model"])
    tags.update(_sweep_tags(naming.preset, naming.sweep_dir))
    return tags


def _sweep_tags(preset: str | None, sweep_dir: Path | None) -> dict[str, str]:
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


def hparams_values(cfg: DictConfig, naming: Naming) -> dict[str, Any]:
    """The hyperparameters of TensorBoard's HPARAMS table: the config groups chosen (objective, model, data,
    ...), the seed, learning rate, batch size, training noise and steps, and every key the sweep varies."""
    out: dict[str, Any] = {"objective": _objective(cfg, naming.choices)}
    for group in HPARAM_GROUPS[1:]:
        if naming.choices.get(group) is not None:
            out[group] = str(naming.choices[group])
    for key in HPARAM_KEYS:
        value = OmegaConf.select(cfg, key, default=None)
        if isinstance(value, (int, float, str, bool)):
            out[key] = value
    for override in naming.varied:
        key, text = _key(override), override.split("=", 1)[-1]
        if key in out:
            continue
        value = OmegaConf.select(cfg, key, default=None) if "@" not in key else None
        out[key] = value if isinstance(value, (int, float, str, bool)) else text
    return out


class Trackers(list):
    """The run's loggers (a list, as Lightning takes it), with what :func:`finish` logs beyond metrics."""

    def __init__(self, loggers=(), cfg: DictConfig | None = None, naming: Naming | None = None, run_dir=None):
        super().__init__(loggers)
        self.cfg, self.naming, self.run_dir = cfg, naming or Naming(), run_dir


def _kind(lg) -> str:
    return str(lg.get("_target_", "")).rsplit(".", 1)[-1]


def build_loggers(
    cfg: DictConfig,
    run_dir: Path,
    experiment: str | Naming | None = None,
    run_name: str | None = None,
    overrides: Sequence[str] = (),
) -> Trackers:
    """The config's loggers. ``experiment``: the job's :class:`Naming` (hybrid_sysid.cli.train: :func:`job_naming`)
    or just an MLflow experiment's name; ``run_name`` the run's (default: the naming's, else the run directory's
    name). Null arguments in conf/logger are filled: a null save_dir is the run directory (TensorBoard in a
    sweep: ``<sweep dir>``, with version = the run name), a null MLflow experiment_name is the naming's
    experiment, a null artifact_location beside a SQLite store is ``<its folder>/mlartifacts/<experiment>``."""
    naming = experiment if isinstance(experiment, Naming) else Naming(experiment or SINGLE_RUNS, run_name)
    run_name = run_name or naming.run or Path(run_dir).name
    out = Trackers((), cfg, naming, Path(run_dir))
    for name, lg in (cfg.get("logger") or {}).items():
        fill: dict[str, Any] = {}
        kind = _kind(lg)
        if "save_dir" in lg and lg.save_dir is None:
            in_sweep = kind == "TensorBoardLogger" and naming.sweep_dir is not None
            fill["save_dir"] = str(naming.sweep_dir if in_sweep else run_dir)
        if kind == "TensorBoardLogger" and "version" in lg and lg.version is None:
            fill["version"] = run_name.replace("/", "_") if naming.sweep_dir is not None else ""
        if kind != "MLFlowLogger":
            out.append(build(lg, f"logger.{name}", **fill))
            continue
        exp_name = str(lg.experiment_name) if lg.get("experiment_name") is not None else naming.experiment
        fill["experiment_name"] = exp_name
        if "run_name" in lg and lg.run_name is None:
            fill["run_name"] = run_name
        fill["tags"] = {**run_tags(cfg, naming, run_dir, overrides), **dict(lg.get("tags") or {})}
        uri, location = str(lg.get("tracking_uri") or ""), lg.get("artifact_location")
        # a sweep's experiment is tagged with its preset and directory; "runs", shared by single runs, is not
        exp_tags = _sweep_tags(naming.preset, naming.sweep_dir) if naming.sweep_dir is not None else {}
        lock = contextlib.nullcontext()
        if uri.startswith("sqlite:///"):
            # parallel jobs share one database: create its tables, the experiment and this run one at a time
            db = Path(uri.removeprefix("sqlite:///"))
            db.parent.mkdir(parents=True, exist_ok=True)
            if location is None:
                location = fill["artifact_location"] = artifact_root(db, exp_name)
            lock = FileLock(str(db) + ".lock")
        with lock:
            logger = build(lg, f"logger.{name}", **fill)
            mlflow_experiment(logger._mlflow_client, exp_name, location, exp_tags)
            logger.experiment  # noqa: B018 - the property creates the run
        out.append(logger)
    return out


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


def hyperparameters(cfg: DictConfig) -> dict:
    """The resolved config flattened to dotted keys (lists as text), e.g. {"model.optim.lr": 0.02}."""
    flat = flatten(OmegaConf.to_container(cfg, resolve=True))
    return {k: v if isinstance(v, (int, float, str, bool)) else str(v) for k, v in flat.items()}


def _as_metrics(rows: Iterable[dict], base) -> dict[str, float]:
    out = {}
    for r in rows:
        out[f"{base(r)}_mean_rel_dev"], out[f"{base(r)}_std_rel_dev"] = r["mean_rel_dev"], r["std_rel_dev"]
    return out


def curve_metrics(rows: Iterable[dict]) -> dict[str, float]:
    """Learning-curve rows as metrics: curve/<split>/noise_<std>/<parameter>_mean_rel_dev (and _std_)."""
    return _as_metrics(rows, lambda r: f"curve/{r['split']}/noise_{r['noise_std']:g}/{r['parameter']}")


def result_metrics(results: Iterable[dict]) -> dict[str, float]:
    """The record's results as metrics: final/<split>/noise_<std>/K<windows>/<parameter>_mean_rel_dev."""
    return _as_metrics(
        results, lambda r: f"final/{r['split']}/noise_{r['noise_std']:g}/K{r.get('windows', 1)}/{r['parameter']}"
    )


def hparams_metrics(metrics: dict[str, float]) -> dict[str, float]:
    """The HPARAMS table's metrics: the test split's mean relative deviations, per noise level, K and parameter."""
    return {k: v for k, v in metrics.items() if k.startswith("final/test/") and k.endswith("_mean_rel_dev")}


def log_metrics(loggers: Sequence, metrics: dict[str, float], step: int) -> None:
    for logger in loggers:
        logger.log_metrics(metrics, step=step)


def finish(loggers: Sequence, results: Iterable[dict], step: int, status: str = "success") -> None:
    """Log the final results (TensorBoard: and the HPARAMS table; MLflow: and the run's files) and close every
    logger."""
    metrics = result_metrics(results)
    cfg, naming, run_dir = (getattr(loggers, a, None) for a in ("cfg", "naming", "run_dir"))
    for logger in loggers:
        logger.log_metrics(metrics, step=step)
        kind = type(logger).__name__
        if cfg is not None and kind == "TensorBoardLogger":
            varied = [_key(o) for o in naming.varied]
            _guarded("the hparams table", _write_hparams, logger, hparams_values(cfg, naming), metrics, varied)
        if run_dir is not None and kind == "MLFlowLogger":
            _guarded("the run's artifacts", _log_run_files, logger.experiment, logger.run_id, run_dir)
        logger.save()
        logger.finalize(status)
        if run_dir is not None and kind == "MLFlowLogger":
            _finished.setdefault(str(Path(run_dir).resolve()), []).append((logger._tracking_uri, logger.run_id))


def _guarded(what: str, fn, *args) -> None:
    try:
        fn(*args)
    except Exception as exc:  # noqa: BLE001 - the record holds every number: a tracker's extra is a warning
        log.warning("%s not written to the tracker: %s: %s", what, type(exc).__name__, exc)


def _write_hparams(logger, params: dict, metrics: dict[str, float], varied: Iterable[str] = ()) -> None:
    """The HPARAMS tab's data (the experiment, this run's hyperparameters, its end), written as Lightning's
    log_hyperparams would with metrics, but naming the final metrics already logged instead of logging new ones.
    The keys in ``varied`` are marked as differing between the runs: the tab shows them first (it shows 5
    hyperparameters until more are ticked)."""
    try:
        from torch.utils.tensorboard.summary import hparams
    except ImportError:  # Lightning writes with tensorboardX when tensorboard is absent
        from tensorboardX.summary import hparams

    experiment, start, end = hparams(params, hparams_metrics(metrics))
    _mark_differing(experiment, set(varied))
    writer = logger.experiment._get_file_writer()
    for summary in (experiment, start, end):
        writer.add_summary(summary)
    writer.flush()


def _mark_differing(experiment, keys: set[str]) -> None:
    """Set ``differs`` on the experiment summary's hyperparameters named in ``keys`` (TensorBoard sorts those first;
    it computes the flag itself only for runs without an experiment summary). Unchanged without the tensorboard
    package's protos."""
    try:
        from tensorboard.plugins.hparams.plugin_data_pb2 import HParamsPluginData
    except ImportError:
        return
    value = experiment.value[0]
    data = HParamsPluginData.FromString(value.metadata.plugin_data.content)
    for info in data.experiment.hparam_infos:
        info.differs = info.name in keys
    value.metadata.plugin_data.content = data.SerializeToString()


def _log_run_files(client, run_id: str, run_dir: Path, figures_only: bool = False) -> None:
    run_dir = Path(run_dir)
    if not figures_only:
        for rel, artifact_path in RUN_ARTIFACTS.items():
            if (run_dir / rel).is_file():
                client.log_artifact(run_id, str(run_dir / rel), artifact_path or None)
    for png in sorted((run_dir / "figures").glob("*.png")):
        client.log_artifact(run_id, str(png), "figures")


def log_run_figures(run_dir: Path) -> None:
    """Add the run's figures (``<run dir>/figures/*.png``, drawn after the run ended) to the MLflow runs this
    process finished in ``run_dir``; nothing without such a run. A failure is a warning."""
    for uri, run_id in _finished.pop(str(Path(run_dir).resolve()), []):
        from mlflow import MlflowClient

        _guarded("the run's figures", _log_run_files, MlflowClient(uri), run_id, run_dir, True)


def log_sweep(config: DictConfig, sweep_dir: Path) -> None:
    """At a sweep's end (hybrid_sysid.report.sweep_callback), for each MLflow logger of the sweep's config: its
    summary table (summary.md, .csv, ...), figures and multirun.yaml as artifacts of the experiment's run
    ``sweep summary``, and summary.md as the experiment's description. A failure is a warning."""
    for lg in (OmegaConf.select(config, "logger", default=None) or {}).values():
        if _kind(lg) == "MLFlowLogger":
            _guarded("the sweep's summary", _log_sweep, config, lg, Path(sweep_dir))


def _log_sweep(config: DictConfig, lg: DictConfig, sweep_dir: Path) -> None:
    from mlflow import MlflowClient
    from mlflow.utils.mlflow_tags import MLFLOW_RUN_NAME

    preset = OmegaConf.select(config, "hydra.runtime.choices.experiment", default=None)
    name = str(lg.experiment_name) if lg.get("experiment_name") is not None else experiment_name(preset, sweep_dir)
    uri, location = str(lg.tracking_uri), lg.get("artifact_location")
    lock = contextlib.nullcontext()
    if uri.startswith("sqlite:///"):
        db = Path(uri.removeprefix("sqlite:///"))
        location = location or artifact_root(db, name)
        lock = FileLock(str(db) + ".lock")
    client, tags = MlflowClient(uri), _sweep_tags(preset, sweep_dir)
    with lock:
        exp_id = mlflow_experiment(client, name, location, tags)
    previous = client.search_runs([exp_id], filter_string="tags.kind = 'sweep'", max_results=1)
    if previous:  # a re-run sweep: the same run, its files replaced
        run_id = previous[0].info.run_id
    else:
        run_id = client.create_run(exp_id, tags={MLFLOW_RUN_NAME: SWEEP_RUN, "kind": "sweep", **tags}).info.run_id
    for pattern in SWEEP_ARTIFACTS:
        for path in sorted(sweep_dir.glob(pattern)):
            client.log_artifact(run_id, str(path))
    for path in sorted((sweep_dir / "figures").glob("*")):
        if path.suffix in (".png", ".pdf", ".svg"):
            client.log_artifact(run_id, str(path), "figures")
    summary = sweep_dir / "summary.md"
    if summary.is_file():
        client.set_experiment_tag(exp_id, "mlflow.note.content", summary.read_text(encoding="utf-8"))
    client.set_terminated(run_id, "FINISHED")
