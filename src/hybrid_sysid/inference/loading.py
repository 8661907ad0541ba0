"""A run directory as an estimator: ``load_estimator`` reads the run (runs.rundir.RunDir), builds its network or
least-squares baseline with the training code's own builders (which refuse a ``_target_`` outside the package's
allow-list before anything is imported), and loads its weights. Every failure is one InputError naming the run."""

from __future__ import annotations

from pathlib import Path

import torch
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import Config, validate
from hybrid_sysid.core.checks import ConfigError, Shown
from hybrid_sysid.inference.estimator import Estimator
from hybrid_sysid.inference.inputs import InputError
from hybrid_sysid.runs.layout import CONFIG
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.training.build import build_baseline, build_model, misfit_words


def load_estimator(run_dir: str | Path, checkpoint: str | None = None) -> Estimator:
    """The trained network of a run directory written by ``hybrid-sysid``, as an estimator of recordings.

    Parameters
    ----------
    run_dir : str or pathlib.Path
        A run directory (it holds ``.hydra/config.yaml`` and ``checkpoints/``), never a checkpoint's path.
    checkpoint : {None, "best", "last"}
        None takes ``checkpoints/best.ckpt`` (what the run's metrics were computed with) or, when the run never
        validated, ``last.ckpt``; "best" or "last" takes that one alone. A baseline run (``baseline=ls_*``, no
        network) estimates with its least-squares fit and ignores it.

    Returns
    -------
    Estimator
        Its ``predict(seat_acc, body_acc, dt)`` gives a table per recording. The run's ``metrics.json`` gives its
        own test error (the flag ``run_error``); None when unreadable.

    Raises
    ------
    InputError
        A ``ValueError``, in one line naming what is wrong: ``run_dir`` no path, no config or checkpoint, a
        checkpoint that cannot be read or does not fit the run's network, a config naming a class outside the
        package and its installed plugins, or values a command line could not give.
    """
    if not isinstance(run_dir, (str, Path)):  # None, bytes or a number reached RunDir as a TypeError
        shown = Shown(repr(run_dir)[:80])
        raise InputError("run_dir", shown, "the path of a run directory, as a str or a pathlib.Path")
    run = RunDir(run_dir)
    cfg = _as_input(run, run.saved_config)
    is_baseline = _as_input(run, lambda: OmegaConf.select(cfg, "baseline", default=None)) is not None
    if not is_baseline:  # the checks below build the network: its size must first be the checkpoint's
        path, state = _as_input(run, run.load_weights, "run", checkpoint)
        _sizes_fit(cfg, run, path, state)
    _checked(run, cfg)
    try:
        record = run.record()
    except ConfigError:  # unreadable: the run's test error is then unknown (the flag run_error says so)
        record = None
    if is_baseline:
        net, baseline = None, _as_input(run, build_baseline, cfg)
    else:
        net, baseline = _network(cfg, run, path, state), None
    try:
        return Estimator(net, cfg, baseline=baseline, record=record)
    except Exception as exc:  # noqa: BLE001 - the data section, read for the trained range, lacks or mistypes keys
        raise InputError("run", Shown(str(run.path)), f"a run whose {CONFIG} can be read ({_one_line(exc)})") from None


def _checked(run: RunDir, cfg: DictConfig) -> None:
    """The saved config gets every check of a command line (config.validate), but those of training on this
    machine: a received run's window of 0 steps or time step of 0 is one line here, not a traceback later."""
    try:
        full = OmegaConf.merge(OmegaConf.structured(Config), {k: v for k, v in cfg.items() if k != "hydra"})
        validate(full, training=False)
    except ConfigError as exc:
        raise InputError(f"run = {run.path}: {exc.key}", exc.value, exc.allowed, exc.missing) from None
    except Exception as exc:  # noqa: BLE001 - a key or a type this version does not have, a section cut short
        raise InputError("run", Shown(str(run.path)), f"a run whose {CONFIG} can be read ({_one_line(exc)})") from None


def _network(cfg: DictConfig, run: RunDir, path: Path, state: dict) -> torch.nn.Module:
    """The run's network with the checkpoint's weights (``state``, read from ``path``), built by the code that
    trained it."""
    model = _as_input(run, build_model, cfg)  # a class the config names is checked before anything is imported
    try:
        model.load_state_dict(state)  # keys "net." and "objective.", as the LightningModule saved them
    except RuntimeError as exc:  # another run's checkpoint: torch lists every mismatched key, one line each
        raise InputError(
            "run",
            Shown(str(run.path)),
            f"a run whose {path.relative_to(run.path)} fits its model.net ({cfg.model.net._target_}): "
            f"{str(exc).splitlines()[0]}",
        ) from None
    return model.net


def _sizes_fit(cfg: DictConfig, run: RunDir, path: Path, state: dict) -> None:
    """The network the config describes has the checkpoint's tensor shapes (training.build.misfit_words)."""
    words = misfit_words(cfg, run.path, path, state)
    if words is not None:
        raise InputError("run", Shown(str(run.path)), words)


def _as_input(run: RunDir, fn, *args):
    """``fn(*args)``, its failures as one InputError naming the run."""
    try:
        return fn(*args)
    except ConfigError as exc:
        raise InputError(exc.key, exc.value, exc.allowed, exc.missing) from None
    except Exception as exc:  # noqa: BLE001 - a config that parses but lacks or mistypes keys
        raise InputError("run", Shown(str(run.path)), f"a run whose {CONFIG} can be read ({_one_line(exc)})") from None


def _one_line(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
