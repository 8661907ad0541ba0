"""IdentificationModule: a network, a swappable objective, the optimiser, and predictions on fixed windows."""

from __future__ import annotations

import lightning as L
import numpy as np
import torch
from torch import nn

from hybrid_sysid.core import stop
from hybrid_sysid.core.options import OPTIMIZERS
from hybrid_sysid.model.metrics import relative_deviation
from hybrid_sysid.model.optim import OptimSettings

LOG_EVERY = 50  # steps between progress-bar updates of the training loss


class IdentificationModule(L.LightningModule):
    """Predicts (p1, p2) from a window of (seat, body) accelerations.

    The network maps signals to physical (p1, p2); the objective maps (pred, batch) to a loss. Lightning's
    automatic optimisation takes the steps (so gradient clipping, accumulation and precision settings of the
    Trainer apply). Validation logs ``val/loss`` (the training objective on clean validation windows: label-free
    for the hybrid objective) and ``val/rel_dev`` (mean relative deviation over both parameters: uses labels).
    The learning curves are recorded by a callback of the training layer (hybrid_sysid.training.callbacks).
    """

    def __init__(
        self,
        net: nn.Module,
        objective: nn.Module,
        optimizer: str = "adamw",
        lr: float = 3e-3,
        weight_decay: float = 0.0,
        schedule: str = "onecycle",
        max_steps: int = 1000,
        warmup_fraction: float = 0.3,
    ):
        super().__init__()
        OptimSettings(optimizer, lr, weight_decay, schedule, warmup_fraction).validate()
        # only plain values in the hyperparameters, so checkpoints load with torch's weights_only default
        self.save_hyperparameters(ignore=["net", "objective"])
        self.net, self.objective = net, objective
        self.val_batches: list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]] = []  # (pred, true, summed loss)

    def forward(self, signals: torch.Tensor) -> torch.Tensor:
        return self.net(signals)

    def training_step(self, batch, batch_idx):
        loss = self.objective(self(batch["signals"]), batch)
        # a network with a second estimate of its own (model.anchored's partner) trains it by the same objective
        for extra in getattr(self.net, "auxiliary", ()):
            loss = loss + self.objective(extra, batch)
        if not torch.isfinite(loss):  # global_step counts the steps taken before this one
            raise FloatingPointError(
                f"training loss is {loss.item()} at step {self.global_step}; lower model.optim.lr or check the data"
            )
        # a self.log call costs a sizeable share of a fast_cnn step (benchmarks/README.md, "Training throughput"):
        # the progress bar's loss follows Lightning's own default logging interval instead (on the steps where the
        # Trainer's log_every_n_steps = LOG_EVERY passes it on to the loggers)
        if (self.global_step + 1) % LOG_EVERY == 0:
            self.log("train/loss", loss.detach(), prog_bar=True, batch_size=len(batch["signals"]))
        return loss

    def validation_step(self, batch, batch_idx):
        pred = self(batch["signals"])
        loss = self.objective(pred, batch).detach() * len(pred)
        self.val_batches.append((pred.detach(), batch["params"], loss))

    def on_validation_epoch_end(self):
        preds, trues, losses = zip(*self.val_batches)
        self.val_batches = []
        pred, true = torch.cat(preds), torch.cat(trues)
        dev = relative_deviation(pred.cpu().numpy(), true.cpu().numpy())
        # with DDP every rank validates the same windows with the same weights: the mean over ranks (sync_dist)
        # is the same value, and keeps the checkpoint's monitor in step across ranks
        self.log("val/loss", torch.stack(losses).sum() / len(pred), sync_dist=True)
        self.log("val/rel_dev", float(dev.mean()), prog_bar=True, sync_dist=True)
        self.log("val/p1_rel_dev", float(dev[:, 0].mean()), sync_dist=True)
        self.log("val/p2_rel_dev", float(dev[:, 1].mean()), sync_dist=True)

    @torch.no_grad()
    def predict_split(self, dm, split: str, noise_std: float, limit: int | None = None, windows: int = 1):
        """Predictions and truth (numpy float64, one row per recording) on a split's fixed windows at one noise
        level; with ``windows`` = K > 1, the mean of the predictions on the recording's K windows."""
        was_training = self.training
        self.eval()
        preds, trues = [], []
        for batch in dm.eval_dataloader(split, noise_std, limit, windows):
            stop.check()  # a safe point (core.stop)
            preds.append(self(batch["signals"].to(self.device)).cpu())
            trues.append(batch["params"])
        self.train(was_training)
        pred = torch.cat(preds).numpy().astype(np.float64)
        true = torch.cat(trues).numpy().astype(np.float64)
        # the data module lays out each recording's K windows in a row. The mean, not the median: the errors of
        # single windows are near symmetric and rarely wild, so every window's estimate is worth its weight
        return pred.reshape(-1, windows, 2).mean(axis=1), true.reshape(-1, windows, 2)[:, 0]

    def configure_optimizers(self):
        hp = self.hparams
        opt = getattr(torch.optim, OPTIMIZERS[hp.optimizer])(self.parameters(), lr=hp.lr, weight_decay=hp.weight_decay)
        if hp.schedule == "constant":
            return opt
        sched = torch.optim.lr_scheduler.OneCycleLR(
            opt, max_lr=hp.lr, total_steps=max(hp.max_steps, 2), pct_start=hp.warmup_fraction
        )
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}
