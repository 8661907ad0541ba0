"""A label-free target from the rest of the recording: ``objective=cross_segment`` (docs/label_free.md).

The label_free objective fits the network to each window's own least-squares p, a function of the very samples the
network reads: the target carries that window's noise, and the network learns it. Here the target is the fit of the
seat over the recording's samples outside the window (``p_out``), whose sensor noise is independent of the
window's: the errors-in-variables maximum likelihood, or the band-passed least squares (``target``). The data
module computes it (hybrid_sysid.data.outside, ``WindowCutter.outside``) when an objective asks through
``outside_fir`` and ``outside_target``.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from torch import nn

from hybrid_sysid.model import arguments
from hybrid_sysid.model.objectives import LABEL_FREE


class CrossSegmentObjective(nn.Module):
    """Mean over the batch of sum_i w_i |p_i - p_out_i| / p_scale_i, without a label read.

    p_out: the fit of the seat over the samples of the window's recording outside the window; se_out: that fit's
    relative standard error. ``target``: "eiv", the errors-in-variables maximum likelihood of the two outside
    segments together (data.outside.fit_joined), started from "ls"; "ls", the band-passed least squares over the
    filtered samples whose whole FIR support lies outside the window (physics.seat_fit). Least squares is biased
    towards zero under noise on the body channel, and the network would learn that bias; the likelihood fit is
    consistent under it (docs/label_free.md). The constructor's default is "ls": a saved config written before the
    argument existed was trained with it. conf/objective/cross_segment.yaml sets "eiv".
    ``fix``: the simulated fault's fix (conf: ``${fault_fix:}``), which the "eiv" target then takes (data.outside):
    the plain fit of a faulted recording is biased, and the network would learn that bias too.
    w_i = 1 / (se_out_i + ``floor``), divided by its mean over the batch, per parameter: each parameter keeps the
    total weight the labelled objective gives it, and within it a row counts by how well its outside fit is
    determined. The floor stops rounding from ranking near-exact fits: below it (1% by default) every fit counts
    alike, and on clean recordings the loss is the labelled one to about 1e-5. A row whose outside fit is not
    defined (NaN) gets weight 0. Model selection: the same loss on the validation windows (``val/loss``).
    ``weighted``: False gives every defined row weight 1. The L1 loss makes the network the conditional median of
    the targets given the window, and weights that follow the target's se (which depends on p, the road and the
    noise) tilt that median towards the p whose outside fits are precise (docs/label_free.md measures it).
    """

    uses_labels = False
    monitor = LABEL_FREE
    fir = None  # the network's window needs no filtered signals: only the outside fit is band-passed
    outside_fir: np.ndarray | None = None  # set below: the band-pass of the outside fit
    outside_target: str | None = None  # set below: ``target``, the fit the data module computes
    outside_fix: str = "none"  # set below: ``fix``, the fault's fix of that fit

    def __init__(
        self,
        p_scale: Sequence[float],
        filter: dict,
        dt: float | None = None,
        floor: float = 0.01,
        target: str = "ls",
        weighted: bool = True,
        fix: str = "none",
    ):
        super().__init__()
        checked = arguments.cross_segment(p_scale, filter, dt, floor, target, weighted, fix)
        self.register_buffer("p_scale", torch.tensor(checked.p_scale))
        self.floor, self.filter, self.outside_fir = checked.floor, checked.filter, checked.outside_fir
        self.target = self.outside_target = target
        self.fix = self.outside_fix = fix
        self.weighted = weighted

    def forward(self, pred: torch.Tensor, batch: dict) -> torch.Tensor:
        if "p_out" not in batch:
            raise KeyError(
                "the batch has no p_out: build the data module with the objective's outside_fir "
                "(hybrid_sysid.training.build.build_datamodule does)"
            )
        p_out, se_out = (batch[k].to(pred) for k in ("p_out", "se_out"))
        valid = torch.isfinite(p_out) & torch.isfinite(se_out)
        w = 1.0 / (se_out.clamp_min(0.0) + self.floor) if self.weighted else torch.ones_like(se_out)
        w = torch.where(valid, w, 0.0)
        # a column without any defined fit keeps weight 0 (and the loss its gradient path) rather than 0 / 0
        w = w / w.mean(dim=0).clamp_min(torch.finfo(w.dtype).tiny)
        err = (pred - torch.where(valid, p_out, pred.detach())) / self.p_scale
        return (w * err.abs()).sum(dim=1).mean()
