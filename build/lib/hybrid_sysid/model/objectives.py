"""Training objectives, one signature: ``loss = objective(pred, batch)``.

pred: (B, 2) predicted (p1, p2) in physical units. batch: the data module's dict, "signals" (B, 2, W) with
seat z'' in channel 0, "params" (B, 2) true p, "rel_vel" / "rel_disp" (B, W) seat-minus-body relative states
re-integrated from t0 over the whole recording and cropped to the window.
"""

from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import nn

from hybrid_sysid.model.checks import check_pair

_NORMS = ("l1", "l2")


class LabelledObjective(nn.Module):
    """J_L (eq. 17): mean over the batch of sum_i |p_i - p~_i|, both divided by ``p_scale``.

    Scaling puts p1 (~8) and p2 (~1200) on one footing; unscaled, p2 alone would drive the gradient. The run's
    config passes the midpoint of the prior of p (``${p_prior:scale}``, hybrid_sysid.config).
    ``norm="l2"`` (squared error) is offered as an alternative; the paper's is l1.
    """

    uses_labels = True  # model selection may then use the labelled val/rel_dev (trainer.monitor=auto)

    def __init__(self, p_scale: Sequence[float], norm: str = "l1"):
        super().__init__()
        if norm not in _NORMS:
            raise ValueError(f"norm = {norm!r} is unknown; allowed: {', '.join(_NORMS)}")
        self.norm = norm
        self.register_buffer("p_scale", torch.tensor(check_pair("p_scale", p_scale)))

    def forward(self, pred: torch.Tensor, batch: dict) -> torch.Tensor:
        err = (pred - batch["params"].to(pred)) / self.p_scale
        err = err.abs() if self.norm == "l1" else err.pow(2)
        return err.sum(dim=1).mean()


class HybridObjective(nn.Module):
    """J_U (eq. 22): squared error of z''_rec = -p1 rel_vel - p2 rel_disp against the recorded seat z''.

    Uses only the signals and the re-integrated relative states, never batch["params"] (no labels).
    Per sample the mean squared residual over the window; with ``normalize`` it is divided by that window's
    mean squared seat acceleration, i.e. the loss becomes 1 - R^2-like and scale-free. Without it a class E
    window (16x the road amplitude of class A, 256x the squared error) would outweigh class A windows by
    orders of magnitude and the network would learn only from rough roads. ``eps`` guards all-zero windows.
    """

    uses_labels = False  # model selection then stays label-free too (trainer.monitor=auto picks val/loss)

    def __init__(self, normalize: bool = True, eps: float = 1e-12):
        super().__init__()
        if not (math.isfinite(eps) and eps >= 0):
            raise ValueError(f"eps = {eps} is invalid; it must be finite and >= 0")
        self.normalize = bool(normalize)
        self.eps = float(eps)

    def forward(self, pred: torch.Tensor, batch: dict) -> torch.Tensor:
        seat = batch["signals"][:, 0].to(pred)
        z_rec = -pred[:, :1] * batch["rel_vel"].to(pred) - pred[:, 1:2] * batch["rel_disp"].to(pred)
        mse = (seat - z_rec).pow(2).mean(dim=1)
        if self.normalize:
            mse = mse / (seat.pow(2).mean(dim=1) + self.eps)
        return mse.mean()


class CombinedObjective(nn.Module):
    """labelled_weight * J_L + hybrid_weight * J_U; other keyword arguments go to the two objectives."""

    def __init__(self, p_scale: Sequence[float], labelled_weight: float = 1.0, hybrid_weight: float = 1.0,
                 norm: str = "l1", normalize: bool = True, eps: float = 1e-12):
        super().__init__()
        for name, w in (("labelled_weight", labelled_weight), ("hybrid_weight", hybrid_weight)):
            if not (math.isfinite(w) and w >= 0):
                raise ValueError(f"objective: {name} = {w} is invalid; it must be finite and >= 0")
        if labelled_weight == 0 and hybrid_weight == 0:
            raise ValueError("objective: labelled_weight and hybrid_weight must not both be zero "
                             f"(got {labelled_weight}, {hybrid_weight}); allowed: >= 0 with a positive sum")
        self.labelled_weight, self.hybrid_weight = float(labelled_weight), float(hybrid_weight)
        self.labelled = LabelledObjective(p_scale=p_scale, norm=norm)
        self.hybrid = HybridObjective(normalize=normalize, eps=eps)
        # with labelled_weight 0 the combination is label-free, and model selection must stay so too
        self.uses_labels = self.labelled_weight > 0

    def forward(self, pred: torch.Tensor, batch: dict) -> torch.Tensor:
        # a zero weight skips its term, so a hybrid-only combination still never reads the labels
        loss = pred.new_zeros(())
        if self.labelled_weight:
            loss = loss + self.labelled_weight * self.labelled(pred, batch)
        if self.hybrid_weight:
            loss = loss + self.hybrid_weight * self.hybrid(pred, batch)
        return loss
