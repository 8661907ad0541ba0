"""TensorBoard's HPARAMS tab: a run's hyperparameters (the config groups chosen, the seed, learning rate, batch
size, training noise and steps, the user's tags, and every key the sweep varies) beside its final test metrics."""

from __future__ import annotations

from typing import Any, Iterable

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config.tags import joined
from hybrid_sysid.core.overrides import parse_override
from hybrid_sysid.training.tracking.naming import Naming, objective_name

# the hyperparameters of the table, beside the config groups chosen and the swept keys
HPARAM_GROUPS = ("objective", "baseline", "model", "data", "noise")
HPARAM_KEYS = (
    "seed",
    "model.optim.lr",
    "model.batch_size",
    "noise.train_std",
    "noise.train_std_max",  # the top of a log-uniform range of training noise (null: train_std alone)
    "trainer.max_steps",
)


def hparams_values(cfg: DictConfig, naming: Naming) -> dict[str, Any]:
    """The hyperparameters of TensorBoard's HPARAMS table: the config groups chosen (objective, model, data,
    ...), the seed, learning rate, batch size, training noise and steps, the config's tags (one text field, when
    any) and every key the sweep varies."""
    out: dict[str, Any] = {"objective": objective_name(cfg, naming.choices)}
    if cfg.get("tags"):
        out["tags"] = joined(cfg.tags)
    for group in HPARAM_GROUPS[1:]:
        if naming.choices.get(group) is not None:
            out[group] = str(naming.choices[group])
    for key in HPARAM_KEYS:
        value = OmegaConf.select(cfg, key, default=None)
        if isinstance(value, (int, float, str, bool)):
            out[key] = value
    for override in naming.varied:
        _, key, text = parse_override(override)
        if key in out:
            continue
        value = OmegaConf.select(cfg, key, default=None) if "@" not in key else None
        out[key] = value if isinstance(value, (int, float, str, bool)) else text
    return out


def hparams_metrics(metrics: dict[str, float]) -> dict[str, float]:
    """The table's metrics: the test split's mean relative deviations, per noise level, K and parameter."""
    return {k: v for k, v in metrics.items() if k.startswith("final/test/") and k.endswith("_mean_rel_dev")}


def write_hparams(logger, params: dict, metrics: dict[str, float], varied: Iterable[str] = ()) -> None:
    """The HPARAMS tab's data (the experiment, this run's hyperparameters, its end), written as Lightning's
    log_hyperparams would with metrics, but naming the final metrics already logged instead of logging new ones.
    The keys in ``varied`` are marked as differing between the runs: the tab shows them first (it shows 5
    hyperparameters until more are ticked)."""
    try:
        from torch.utils.tensorboard.summary import hparams  # deferred
    except ImportError:  # Lightning writes with tensorboardX when tensorboard is absent
        from tensorboardX.summary import hparams  # deferred

    experiment, start, end = hparams(params, hparams_metrics(metrics))
    mark_differing(experiment, set(varied))
    writer = logger.experiment.file_writer  # open once the run's metrics were logged to it
    if writer is None:
        raise RuntimeError("the run's TensorBoard file is not open")
    for summary in (experiment, start, end):
        writer.add_summary(summary)
    writer.flush()


def mark_differing(experiment, keys: set[str]) -> None:
    """Set ``differs`` on the experiment summary's hyperparameters named in ``keys`` (TensorBoard sorts those first;
    it computes the flag itself only for runs without an experiment summary). Unchanged without the tensorboard
    package's protos."""
    try:
        from tensorboard.plugins.hparams.plugin_data_pb2 import HParamsPluginData  # deferred
    except ImportError:
        return
    value = experiment.value[0]
    data = HParamsPluginData.FromString(value.metadata.plugin_data.content)
    for info in data.experiment.hparam_infos:
        info.differs = info.name in keys
    value.metadata.plugin_data.content = data.SerializeToString()
