"""The checks of a config with data.path (``data=recordings``) before any work: config.validate calls
``check_recordings`` in place of the simulator's checks. The files are scanned here (data.recordings_files), so a
bad file, a step other than data.dt, a recording too short for what reads it, labels that do not fit, or an
objective that needs labels the recordings lack is one line before any directory is made."""

from __future__ import annotations

from dataclasses import replace

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config.targets import build
from hybrid_sysid.core.checks import ConfigError, Shown, bad
from hybrid_sysid.data.recordings_files import UNNAMED, index, split_recordings
from hybrid_sysid.data.spec import DT_RTOL, MIN_FILTERED, DatasetSpec, check_eval_windows, starts_offered
from hybrid_sysid.physics.sensors import SensorFaults

LABEL_MONITORS = ("val/rel_dev", "val/p1_rel_dev", "val/p2_rel_dev")  # what model selection reads labels through
UNREAD = 2**31 - 1  # the length a saved config's checks assume when no file is read: every window fits
REFERENCE_TAPS = 151  # the band-pass of the reference fit's least-squares start (conf/baseline/eiv.yaml)


def checked(cfg: DictConfig, spec: DatasetSpec, training: bool = True, trains: bool = True) -> DatasetSpec:
    """config.validate's step for data.path: ``spec`` as it is without one, else ``check_recordings``."""
    if cfg.data.get("path") is None:
        return spec
    return check_recordings(cfg, spec, training, trains)


def check_recordings(cfg: DictConfig, spec: DatasetSpec, training: bool = True, trains: bool = True) -> DatasetSpec:
    """ConfigError at the first thing of data.path, data.labels or the config that does not fit; returns the spec
    the window checks read, of the shortest recording's length. ``training`` False: a saved config read to estimate
    with (predict, load_estimator), whose files are not read. ``trains`` False: an evaluation, whose network is
    trained already (so it may have read labels)."""
    d = cfg.data
    task = cfg.get("task", "train")
    if task != "train":
        bad("task", task, "train with data.path: transfer and tuned simulate their own data")
    if SensorFaults(**(cfg.get("sensor") or {})).active:
        bad("sensor", OmegaConf.to_container(cfg.sensor), "no simulated sensor faults with data.path (sensor=none)")
    if cfg.data.get("module") is not None:
        bad("data.module", Shown(str(cfg.data.module.get("_target_"))), "null with data.path: one data module a run")
    if cfg.get("baseline") is not None and cfg.baseline.get("span") == "series":
        bad("baseline.span", "series", "window with data.path (span: series reads a simulated dataset whole)")
    if not training:
        return replace(spec, n_steps=UNREAD)
    if not str(d.path).strip():  # data=recordings without data.path
        raise ConfigError("data.path", missing=True, allowed="a CSV or .npz file of recordings, or a folder of them")
    if d.path == UNNAMED:
        raise ConfigError(
            "data.path",
            missing=True,
            allowed="the recordings to evaluate on (data.path=FILE_OR_FOLDER): a run's saved config names files of "
            "the machine it ran on, read only when named again; its metrics.json lists them (data_files)",
        )
    objective = build(cfg.objective, "objective") if cfg.get("baseline") is None else None
    if trains and d.get("labels") is None:
        check_label_free(cfg, objective)

    idx = index(d.path)
    if abs(idx.dt - d.dt) > DT_RTOL * idx.dt:
        bad("data.dt", d.dt, f"the step of data.path's files, {idx.dt:.9g} s (data.dt={idx.dt:.9g})")
    steps = idx.steps
    taps = 0 if objective is None or objective.outside_fir is None else len(objective.outside_fir)
    outside = "objective.outside_fir (objective=cross_segment)" if taps else None
    need, why = int(d.window), "data.window"
    if outside:
        extra = 2 * (taps - 1) + 2 * (taps + MIN_FILTERED - 1)
        need, why = need + extra, f"data.window + {extra} for the fit outside each window, {outside}"
    if d.get("labels") is None and REFERENCE_TAPS + MIN_FILTERED - 1 > need:
        need, why = REFERENCE_TAPS + MIN_FILTERED - 1, "the reference fit's band-pass"
    short = int(steps.argmin())
    if steps[short] < need:
        r = idx.recordings[short]
        bad(
            f"data.path = {idx.path_of(r.file)}: recording {r.name!r}",
            Shown(f"{r.steps} steps"),
            f"at least {need} steps ({why})",
        )
    if d.get("labels") is not None:
        from hybrid_sysid.data.recordings_labels import read_labels  # deferred

        read_labels(d.labels, [r.name for r in idx.recordings])
    try:
        split_recordings(len(steps), d.train_fraction, d.val_fraction, d.seed)
    except ConfigError as exc:
        raise exc.under("data") from None
    check_windows(cfg, idx, short)
    return replace(spec, n_steps=int(steps[short]))


def check_label_free(cfg: DictConfig, objective) -> None:
    """Without labels, training and model selection read none: a labelled objective (``objective``, built; None
    for a baseline), or a monitor through val/rel_dev, is refused."""
    if objective is not None:
        if objective.uses_labels:
            bad(
                "objective",
                Shown(str(cfg.objective.get("_target_"))),
                "an objective that reads no labels (objective=hybrid, label_free, cross_segment; estimator=eiv or "
                "anchored_label_free), since data.labels is null: data.path's recordings have none",
            )
        if cfg.trainer.monitor in LABEL_MONITORS:
            bad("trainer.monitor", cfg.trainer.monitor, "auto or val/loss, since data.labels is null (no labels)")
    for name, node in (cfg.get("callbacks") or {}).items():
        if isinstance(node, DictConfig) and node.get("monitor") in LABEL_MONITORS:
            bad(f"callbacks.{name}.monitor", node.monitor, "auto or val/loss, since data.labels is null (no labels)")


def check_windows(cfg: DictConfig, idx, short: int) -> None:
    """Every K of evaluation.windows fits in the shortest recording (distinct window starts): the range of
    data.spec.check_eval_windows, in words naming that recording."""
    ks = list(cfg.evaluation.windows)
    r = idx.recordings[short]
    starts = starts_offered(r.steps, int(cfg.data.window))
    try:
        check_eval_windows(ks, starts, "evaluation.windows")
    except ConfigError:
        bad(
            "evaluation.windows",
            ks,
            f"a non-empty list of K in [1, {starts}]: the window starts of the shortest recording, {r.name!r} of "
            f"{r.file} ({r.steps} steps, data.window = {cfg.data.window})",
        )
