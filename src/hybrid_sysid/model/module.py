"""ParameterEstimator: a network, a swappable objective, the optimiser, and evaluation on fixed windows."""

from __future__ import annotations

import math
import time

import lightning as L
import numpy as np
import torch
from torch import nn

from hybrid_sysid.model.metrics import relative_deviation, summarise

OPTIMIZERS = {"adam": torch.optim.Adam, "adamw": torch.optim.AdamW}
SCHEDULES = ("constant", "onecycle", "cosine")


class ParameterEstimator(L.LightningModule):
    """Predicts (p1, p2) from a window of (seat, body) accelerations.

    The network maps signals to physical (p1, p2); the objective maps (pred, batch) to a loss. Validation logs
    ``val/loss`` (the training objective on clean validation windows: label-free for the hybrid objective) and
    ``val/rel_dev`` (mean relative deviation over both parameters: uses labels).
    Every validation also records learning-curve rows (training subset and test at each noise level) when
    ``curve_sets`` is given, as (split, noise_std) pairs evaluated through the data module.
    """

    def __init__(self, net: nn.Module, objective: nn.Module, optimizer: str = "adamw", lr: float = 3e-3,
                 weight_decay: float = 0.0, schedule: str = "onecycle", max_steps: int = 1000,
                 warmup_fraction: float = 0.3, curve_sets: tuple = (), curve_train_limit: int = 1000):
        super().__init__()
        if optimizer not in OPTIMIZERS:
            raise ValueError(f"model.optim.name = {optimizer!r} is unknown; allowed: {', '.join(OPTIMIZERS)}")
        if not lr > 0:
            raise ValueError(f"model.optim.lr = {lr} is not allowed: must be > 0")
        if schedule not in SCHEDULES:
            raise ValueError(f"model.optim.schedule = {schedule!r} is unknown; allowed: {', '.join(SCHEDULES)}")
        # only plain values in the hyperparameters, so checkpoints load with torch's weights_only default
        self.save_hyperparameters(ignore=["net", "objective"])
        self.net, self.objective = net, objective
        # The step is written out in training_step: Lightning's automatic optimisation wraps it in a closure
        # and several hook layers, ~0.3 ms a step of pure Python (measured on a trivial model; the project's
        # step against a plain loop: benchmarks/training_throughput.py).
        self.automatic_optimization = False
        self.curve_rows: list[dict] = []
        self._t0: float | None = None
        self._eval_seconds = 0.0  # time spent evaluating, kept out of the curves' training time
        self._eval_t0 = 0.0
        self._val_pred: list[torch.Tensor] = []
        self._val_true: list[torch.Tensor] = []
        self._val_loss: list[torch.Tensor] = []

    def __setattr__(self, name, value):
        # Lightning sets _current_fx_name around every hook it calls, ~30 times a step; nn.Module's
        # __setattr__ first checks each value against parameters, buffers and submodules. A plain string
        # or None needs none of that (same __dict__ entry either way): ~0.1 ms a step saved, measured with
        # benchmarks/training_throughput.py --tiny.
        if name == "_current_fx_name":
            self.__dict__[name] = value
        else:
            super().__setattr__(name, value)

    @property
    def trained_seconds(self) -> float:
        """Training wall time so far, this session and any resumed one, evaluations excluded."""
        return 0.0 if self._t0 is None else time.perf_counter() - self._t0 - self._eval_seconds

    def on_save_checkpoint(self, checkpoint):
        checkpoint["hybrid_sysid"] = {"curve_rows": self.curve_rows, "train_seconds": self.trained_seconds}

    def on_load_checkpoint(self, checkpoint):
        state = checkpoint.get("hybrid_sysid", {})
        self.curve_rows = list(state.get("curve_rows", []))
        # continue the training clock from the saved total
        self._resumed_seconds = state.get("train_seconds", 0.0)
        # and the window stream where the checkpoint left it, not at its beginning (this hook runs before
        # Lightning starts iterating the training data; one batch per step)
        dm = getattr(self.trainer, "datamodule", None) if self._trainer is not None else None
        if dm is not None and hasattr(dm, "train_windows"):
            dm.train_windows.resume_at(checkpoint["global_step"])

    def forward(self, signals: torch.Tensor) -> torch.Tensor:
        return self.net(signals)

    def training_step(self, batch, batch_idx):
        if self._t0 is None:
            self._t0 = time.perf_counter() - getattr(self, "_resumed_seconds", 0.0)
        step = self.global_step  # counts optimizer steps, so read it before this one
        loss = self.objective(self(batch["signals"]), batch)
        if not torch.isfinite(loss):
            raise FloatingPointError(f"training loss is {loss.item()} at step {step}; "
                                     "lower model.optim.lr or check the data")
        opt = self.optimizers()
        opt.zero_grad(set_to_none=True)
        self.manual_backward(loss)
        opt.step()
        sched = self.lr_schedulers()
        if sched is not None:
            sched.step()
        # Lightning's self.log costs ~1.8 ms (7% of a fast_cnn step) a call: the progress bar's loss is
        # refreshed every 50 steps, Lightning's own default logging interval (every 10th cost ~0.15 ms a step)
        if step % 50 == 0:
            self.log("train/loss", loss.detach(), prog_bar=True, batch_size=len(batch["signals"]))

    def on_validation_start(self):
        self._eval_t0 = time.perf_counter()

    def validation_step(self, batch, batch_idx):
        pred = self(batch["signals"])
        self._val_loss.append(self.objective(pred, batch).detach() * len(pred))
        self._val_pred.append(pred.detach())
        self._val_true.append(batch["params"])

    def on_validation_epoch_end(self):
        self._record_validation()
        # every second of evaluation (curves included) is kept out of the training clock; the checkpoint
        # saved right after this hook stores that clock
        self._eval_seconds += time.perf_counter() - self._eval_t0

    def _record_validation(self):
        pred, true = torch.cat(self._val_pred), torch.cat(self._val_true)
        loss = torch.stack(self._val_loss).sum() / len(pred)
        self._val_pred, self._val_true, self._val_loss = [], [], []
        dev = relative_deviation(pred.cpu().numpy(), true.cpu().numpy())
        self.log("val/loss", loss)
        self.log("val/rel_dev", float(dev.mean()), prog_bar=True)
        self.log("val/p1_rel_dev", float(dev[:, 0].mean()))
        self.log("val/p2_rel_dev", float(dev[:, 1].mean()))
        if self.trainer.sanity_checking or not self.hparams.curve_sets:
            return
        elapsed = self.trained_seconds - (time.perf_counter() - self._eval_t0)
        dm = self.trainer.datamodule
        for split, std in self.hparams.curve_sets:
            limit = self.hparams.curve_train_limit if split == "train" else None
            p, t = self.predict_split(dm, split, std, limit)
            self.curve_rows += summarise(p, t, step=self.global_step, seconds=round(elapsed, 3),
                                         split=split, noise_std=std)

    @torch.no_grad()
    def predict_split(self, dm, split: str, noise_std: float, limit: int | None = None, windows: int = 1):
        """Predictions and truth (numpy float64, one row per recording) on a split's fixed windows at one noise
        level; with ``windows`` = K > 1, the mean of the predictions on the recording's K windows."""
        was_training = self.training
        self.eval()
        preds, trues = [], []
        for batch in dm.eval_dataloader(split, noise_std, limit, windows):
            preds.append(self(batch["signals"].to(self.device)).cpu())
            trues.append(batch["params"])
        self.train(was_training)
        pred = torch.cat(preds).numpy().astype(np.float64)
        true = torch.cat(trues).numpy().astype(np.float64)
        # the data module lays out each recording's K windows in a row. The mean, not the median: measured on
        # the band-pass least-squares window baseline (data=default, test, noise std 0.01, K = 8), the mean gave
        # 2.9% / 1.9% (p1 / p2), the median 3.3% / 1.9%; the per-window errors are near symmetric and rarely wild.
        return pred.reshape(-1, windows, 2).mean(axis=1), true.reshape(-1, windows, 2)[:, 0]

    def configure_optimizers(self):
        hp = self.hparams
        opt = OPTIMIZERS[hp.optimizer](self.parameters(), lr=hp.lr, weight_decay=hp.weight_decay)
        if hp.schedule == "constant":
            return opt
        if hp.schedule == "onecycle":
            sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=hp.lr, total_steps=max(hp.max_steps, 2),
                                                        pct_start=hp.warmup_fraction)
        else:
            sched = torch.optim.lr_scheduler.LambdaLR(
                opt, lambda s: 0.5 * (1 + math.cos(math.pi * min(s, hp.max_steps) / max(hp.max_steps, 1))))
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}
