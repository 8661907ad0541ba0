"""The trainer section's checks: the values no other object owns (steps, threads, devices, the monitor), then
Lightning's own checks of its arguments, run by building the run's ``lightning.Trainer`` without a run. A value
Lightning refuses (``trainer.devices=0``, ``+trainer.extra.max_epochs=-5``) is then one line naming its key
before any directory, not a traceback after the data's simulation."""

from __future__ import annotations

import logging
import numbers
import warnings
from contextlib import contextmanager

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.core.checks import ConfigError, bad, check_choice
from hybrid_sysid.core.options import MONITORS, PROFILERS
from hybrid_sysid.core.ranks import check_world

# torch's threads, and the road simulation's thread pool of as many: far above any machine's cores, and at 100000
# Python cannot start them ("can't start new thread")
THREADS_MAX = 1024
# processes on one node: Lightning starts every one of them itself on the CPU (one per device)
DEVICES_MAX = 256
# the accelerators Lightning knows (gpu is its name for cuda or mps)
ACCELERATORS = ("auto", "cpu", "gpu", "cuda", "mps", "tpu")


def _whole(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_trainer(t: DictConfig) -> None:
    """The trainer's values that no other object checks, each against its range."""
    if t.max_steps < 1:
        bad("trainer.max_steps", t.max_steps, "must be >= 1")
    if t.eval_every_n_steps < 1:
        bad("trainer.eval_every_n_steps", t.eval_every_n_steps, "must be >= 1")
    curve_every = t.get("curve_every_n_steps")
    if curve_every is not None and not (curve_every >= 1 and curve_every % t.eval_every_n_steps == 0):
        bad(
            "trainer.curve_every_n_steps",
            curve_every,
            f"a multiple of trainer.eval_every_n_steps = {t.eval_every_n_steps} (curve points are taken at "
            "validations), or null for every validation",
        )
    if t.threads is not None and not 1 <= t.threads <= THREADS_MAX:
        bad("trainer.threads", t.threads, f"must lie in [1, {THREADS_MAX}], or null for torch's default")
    check_choice("trainer.accelerator", t.accelerator, ACCELERATORS)
    _check_devices(t.devices)
    check_choice("trainer.monitor", t.monitor, MONITORS)
    check_world(t.get("num_nodes", 1), t.devices)  # against the processes the launcher started (core.ranks)
    if not (isinstance(t.progress_bar, bool) or t.progress_bar == "auto"):
        bad("trainer.progress_bar", t.progress_bar, "true, false or auto (a bar when stdout is a terminal)")
    if t.get("profiler") is not None:
        check_choice("trainer.profiler", t.profiler, PROFILERS)


def _check_devices(devices) -> None:
    """A count of processes a node, auto, or a list of device indices (GPUs); Lightning checks the rest."""
    allowed = f"a number of devices in [1, {DEVICES_MAX}], auto, or a list of device indices such as [0, 1]"
    if _whole(devices):
        if not 1 <= devices <= DEVICES_MAX:
            bad("trainer.devices", devices, allowed)
    elif OmegaConf.is_list(devices) or isinstance(devices, list):
        if not (0 < len(devices) <= DEVICES_MAX and all(_whole(d) and 0 <= d < DEVICES_MAX for d in devices)):
            bad("trainer.devices", list(devices), allowed)
    elif devices != "auto":
        bad("trainer.devices", devices, allowed)


@contextmanager
def _quiet_lightning():
    """Within: Lightning's lines on the devices it found, and its warnings, are not printed (the run prints them
    when it trains)."""
    loggers = [logging.getLogger(n) for n in ("lightning", "lightning.pytorch", "lightning.fabric")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():  # its hints (srun found, few workers) come again when the run trains
            warnings.simplefilter("ignore")
            yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def check_trainer_arguments(t: DictConfig) -> None:
    """Lightning's checks of the trainer's arguments, as the run passes them (training/build.py), run by building a
    ``lightning.Trainer`` that writes nothing: first without ``trainer.extra``, whose refusal names
    trainer.devices or trainer.accelerator, then with each of its keys alone, whose refusal names that key, then
    with all of them. Building one takes milliseconds; nothing starts, no file is written."""
    base = dict(
        max_steps=t.max_steps,
        val_check_interval=t.eval_every_n_steps,
        check_val_every_n_epoch=None,
        accelerator=t.accelerator,
        devices=OmegaConf.to_object(t.devices) if OmegaConf.is_config(t.devices) else t.devices,
        num_nodes=t.get("num_nodes", 1),
    )  # not deterministic: Lightning would set torch's deterministic mode for the whole process at once
    extra = OmegaConf.to_container(t.get("extra") or OmegaConf.create({}), resolve=True)
    for key in extra:
        if not isinstance(key, str) or key in ("logger", "callbacks", "plugins", "enable_checkpointing"):
            bad(f"trainer.extra.{key}", extra[key], "an argument of lightning.Trainer the run does not set itself")
    _build(base, "trainer.devices" if "devices" in _refusal(base) else "trainer.accelerator")
    for key, value in extra.items():
        _build({**base, key: value}, f"trainer.extra.{key}", value)
    if len(extra) > 1:
        _build({**base, **extra}, "trainer.extra", extra)


def _refusal(arguments: dict) -> str:
    """Lightning's refusal of ``arguments`` in its words, "" when it builds them."""
    try:
        _trainer(arguments)
    except Exception as exc:  # noqa: BLE001 - MisconfigurationException, TypeError, ValueError...
        return str(exc)
    return ""


def _build(arguments: dict, key: str, value=None) -> None:
    try:
        _trainer(arguments)
    except Exception as exc:  # noqa: BLE001 - Lightning raises its MisconfigurationException, TypeError, ValueError
        shown = arguments.get(key.rsplit(".", 1)[-1]) if value is None else value
        words = " ".join(str(exc).split())[:300]
        raise ConfigError(key, shown, f"an argument lightning.Trainer takes ({type(exc).__name__}: {words})") from None


def _trainer(arguments: dict):
    import lightning as L  # deferred

    with _quiet_lightning():
        return L.Trainer(
            logger=False, enable_checkpointing=False, enable_progress_bar=False, enable_model_summary=False, **arguments
        )
