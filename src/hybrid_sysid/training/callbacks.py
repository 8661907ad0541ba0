"""Lightning callbacks of the training layer: the training clock, the learning curves, the run's checkpoints.

Both keep their state in the run's checkpoints (Lightning saves a callback's ``state_dict``), so a resumed run
carries on its clock and its curve.
"""

from __future__ import annotations

import io
import time
from pathlib import Path
from typing import Sequence

import lightning as L
import torch
from lightning.pytorch.plugins.io import TorchCheckpointIO

from hybrid_sysid.core import steps, stop
from hybrid_sysid.core.checks import Shown, bad
from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.model.metrics import summarise
from hybrid_sysid.training.tracking import curve_metrics, log_metrics

CURVE_COLUMNS = ["step", "seconds", "split", "noise_std", "parameter", "mean_rel_dev", "std_rel_dev", "n"]


class TrainingClock(L.Callback):
    """Training wall time: from the first training batch on, every validation (learning curves included) left
    out, and the time trained before a resume added."""

    def __init__(self):
        self.earlier = 0.0  # seconds trained before a resume (from the checkpoint)
        self.start: float | None = None  # the first training batch of this process
        self.paused = 0.0  # seconds of evaluation since then
        self.pause_start: float | None = None  # set while an evaluation runs

    @property
    def seconds(self) -> float:
        """Training time so far; while an evaluation runs, the time at its start."""
        if self.start is None:
            return self.earlier
        now = time.perf_counter() if self.pause_start is None else self.pause_start
        return self.earlier + now - self.start - self.paused

    def on_train_batch_start(self, trainer, pl_module, batch, batch_idx):
        if self.start is None:
            self.start = time.perf_counter()

    def on_validation_start(self, trainer, pl_module):
        if self.start is not None:  # not the sanity check before training
            self.pause_start = time.perf_counter()

    def on_validation_end(self, trainer, pl_module):
        # before ModelCheckpoint's on_validation_end (Lightning runs checkpoint callbacks last), so the
        # checkpoint saved after a validation holds the clock without it
        if self.pause_start is not None:
            self.paused += time.perf_counter() - self.pause_start
            self.pause_start = None

    def state_dict(self) -> dict:
        return {"seconds": self.seconds}

    def load_state_dict(self, state_dict: dict) -> None:
        self.earlier = float(state_dict["seconds"])


class LearningCurves(L.Callback):
    """At every validation (or at those whose step is a multiple of ``every_n_steps``, and the last), the
    relative deviations on the training split's first ``train_limit`` recordings (clean) and on the test split
    at each of ``test_noise``, through the model's ``predict_split`` on the data module's fixed windows.
    ``rows`` holds one row per parameter and evaluation (``CURVE_COLUMNS``), with the optimiser step and the
    training time of ``clock``; the same rows go to the trainer's loggers, if any. A curve point evaluates 400 +
    400 per noise level windows on the default data (as many training windows as test recordings: a curve needs
    the trend, and a point costs CPU the peer script of benchmarks/peer.py does not spend), several times a
    validation's cost, so a sweep may take fewer points than it validates."""

    def __init__(
        self,
        clock: TrainingClock,
        test_noise: Sequence[float],
        train_limit: int = 400,
        every_n_steps: int | None = None,
    ):
        self.clock, self.train_limit, self.every_n_steps = clock, train_limit, every_n_steps
        self.sets = [("train", 0.0)] + [("test", float(s)) for s in test_noise]
        self.rows: list[dict] = []

    def on_validation_epoch_end(self, trainer, pl_module):
        if trainer.sanity_checking or not trainer.is_global_zero:  # with DDP: rank 0 alone
            return
        step, last = trainer.global_step, trainer.global_step >= trainer.max_steps
        if self.every_n_steps and step % self.every_n_steps and not last:
            return
        seconds = round(self.clock.seconds, 3)
        new = []
        for split, std in self.sets:
            limit = self.train_limit if split == "train" else None
            pred, true = pl_module.predict_split(trainer.datamodule, split, std, limit)
            new += summarise(pred, true, step=trainer.global_step, seconds=seconds, split=split, noise_std=std)
        self.rows += new
        log_metrics(trainer.loggers, curve_metrics(new), trainer.global_step)

    def state_dict(self) -> dict:
        return {"rows": self.rows}

    def load_state_dict(self, state_dict: dict) -> None:
        self.rows = list(state_dict["rows"])


class RunCheckpoint(L.pytorch.callbacks.ModelCheckpoint):
    """ModelCheckpoint whose saved state names its files relative to its directory, so a run directory that was
    moved or copied resumes with its best score and best file (Lightning drops both when the saved absolute
    directory differs from the current one, and a worse checkpoint would then be taken as the best). Files are
    always rewritten in place (no best-v1.ckpt / last-v1.ckpt)."""

    _PATHS = ("best_model_path", "kth_best_model_path", "last_model_path")

    def __init__(self, **kwargs):
        super().__init__(enable_version_counter=False, **kwargs)

    def state_dict(self) -> dict:
        state = super().state_dict()
        state.update({k: Path(state[k]).name if state.get(k) else "" for k in self._PATHS})
        state["best_k_models"] = {Path(p).name: v for p, v in state.get("best_k_models", {}).items()}
        state["dirpath"] = "."
        return state

    def load_state_dict(self, state_dict: dict) -> None:
        here = Path(self.dirpath)
        state = dict(state_dict)
        named = [state[k] for k in self._PATHS if state.get(k)] + list(state.get("best_k_models", {}))
        if any(Path(p).name != p for p in named):
            bad(
                "resume",
                Shown(str(here.parent)),
                "a run whose checkpoints name their files within the run (this one was saved by a version of "
                "hybrid-sysid before 0.2, with absolute paths); train it anew",
            )
        state.update({k: str(here / state[k]) if state.get(k) else "" for k in self._PATHS})
        state["best_k_models"] = {str(here / p): v for p, v in state.get("best_k_models", {}).items()}
        state["dirpath"] = self.dirpath
        super().load_state_dict(state)


class AtomicCheckpointIO(TorchCheckpointIO):
    """Saves a checkpoint into a temporary file beside it, renamed over it (core.files.write_atomic). Lightning
    writes a local checkpoint through fsspec, whose temporary file lies in the system's temp folder: where the
    run is on another file system, the move is a copy, and a full disk cut it short in place of the previous,
    good checkpoint."""

    def save_checkpoint(self, checkpoint, path, storage_options=None) -> None:
        if storage_options is not None:
            return super().save_checkpoint(checkpoint, path, storage_options)  # Lightning refuses them
        buffer = io.BytesIO()
        torch.save(checkpoint, buffer)
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, lambda tmp: tmp.write_bytes(buffer.getbuffer()))


class StopAtSafePoints(L.Callback):
    """The training's safe points (core.stop): after every training and validation batch, a termination signal
    that the command's handler requested ends the fit with Interrupted, raised here rather than from the handler."""

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        stop.check()

    def on_validation_batch_end(self, trainer, pl_module, outputs, batch, batch_idx, dataloader_idx=0) -> None:
        stop.check()


class ValidateAtEnd(L.Callback):
    """A validation at the last step, whether or not it falls on trainer.eval_every_n_steps: a run shorter than
    the interval is validated and has a best checkpoint. Lightning validates when training is asked to stop
    (``should_stop``), and stopping at max_steps changes nothing else; where the last step is a validation step
    already, it is validated once, as before."""

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        if trainer.max_steps > 0 and trainer.global_step >= trainer.max_steps:
            trainer.should_stop = True


class StepReports(L.Callback):
    """The optimiser steps to whoever listens (core.steps: a sweep's worker), on rank 0: at the first step and at
    each twentieth of trainer.max_steps, so a sweep times a kind of job before one of its jobs ends."""

    def __init__(self):
        self.next = 0

    def on_train_start(self, trainer, pl_module) -> None:
        self.next = trainer.global_step
        self._report(trainer)

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        if trainer.global_step >= self.next:
            self._report(trainer)

    def _report(self, trainer) -> None:
        total = trainer.max_steps
        if total <= 0 or not trainer.is_global_zero or not steps.listening():
            self.next = float("inf")  # nobody listens for this fit: one check a step
            return
        steps.report(trainer.global_step, total)
        every = max(total // steps.PARTS, 1)
        self.next = (trainer.global_step // every + 1) * every
