"""Training objectives, one signature: ``loss = objective(pred, batch)``.

pred: (B, 2) predicted (p1, p2) in physical units. batch: the data module's dict, "signals" (B, 2, W) with
seat z'' in channel 0, "params" (B, 2) true p, "rel_vel" / "rel_disp" (B, W) seat-minus-body relative states
re-integrated from t0 over the whole recording and cropped to the window (or from the window's start, with
data.integration=window); with a filter, "seat_f", "rel_vel_f", "rel_disp_f": the three through the band-pass.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from torch import nn

from hybrid_sysid.model import arguments
from hybrid_sysid.physics import relative_states

# model selection under trainer.monitor=auto: the labelled relative deviation, or the objective's own loss on the
# validation windows, which keeps a label-free run label-free
LABELLED, LABEL_FREE = "val/rel_dev", "val/loss"
EPS = 1e-12  # guards the normalisation of an all-zero (parked) window
RIDGE = 1e-9  # the least-squares target's relative ridge: a window of no motion stays finite


def noise_gram(fir: np.ndarray, dt: float, measurement: str) -> np.ndarray:
    """(3, 3) G with Var(filtered residual) = sigma^2 (1, p1, p2) G (1, p1, p2)^T under white noise of std sigma
    on both channels, the residual being seat_f + p1 rel_vel_f + p2 rel_disp_f.

    Summed over the two channels: the outer products of the filtered responses of (seat, rel_vel, rel_disp) to
    one unit impulse of that channel. Integration turns the impulse into a step and a ramp; a band-pass of zero
    DC and zero ramp gain (symmetric, sum 0) ends both, so every response is finite.
    """
    taps = len(fir)
    n = 3 * taps
    gram = np.zeros((3, 3))
    for channel in (0, 1):
        acc = np.zeros((2, n))
        acc[channel, taps] = 1.0
        vel, disp = relative_states(acc[0], acc[1], dt, measurement)
        rows = np.stack([np.convolve(v, fir, mode="valid") for v in (acc[0], vel, disp)])
        gram += rows @ rows.T
    return gram


class LabelledObjective(nn.Module):
    """J_L (eq. 18): mean over the batch of sum_i |p_i - p~_i|, both divided by ``p_scale``.

    Scaling puts p1 (~8) and p2 (~1200) on one footing; unscaled, p2 alone would drive the gradient. The run's
    config passes the midpoint of the prior of p (``${p_prior:scale}``, hybrid_sysid.config).
    """

    uses_labels = True
    monitor = LABELLED
    fir = None  # no band-pass: the data module adds no filtered signals to the batches
    outside_fir = None  # no fit over the rest of the recording

    def __init__(self, p_scale: Sequence[float]):
        super().__init__()
        self.register_buffer("p_scale", torch.tensor(arguments.labelled(p_scale)))

    def forward(self, pred: torch.Tensor, batch: dict) -> torch.Tensor:
        err = (pred - batch["params"].to(pred)) / self.p_scale
        return err.abs().sum(dim=1).mean()


class HybridObjective(nn.Module):
    """J_U (eq. 23): squared error of z''_rec = -p1 rel_vel - p2 rel_disp against the recorded seat z''.

    Uses only the signals and the re-integrated relative states, never batch["params"] (no labels).
    Per sample the mean squared residual over the window; with ``normalize`` it is divided by that window's
    mean squared seat acceleration, i.e. the loss becomes 1 - R^2-like and scale-free. Without it a class E
    window (16x the road amplitude of class A, 256x the squared error) would outweigh class A windows by
    orders of magnitude and the network would learn only from rough roads. EPS guards all-zero windows.

    ``filter`` ({low_hz, high_hz, taps}, the band-pass of the least-squares baseline; needs the data's ``dt``):
    the residual of the three signals through that zero-phase band-pass (the batch's "seat_f", "rel_vel_f",
    "rel_disp_f", built by the data module). The seat equation is linear and time invariant, so it holds for
    the filtered signals exactly, while the filter drops the drift of integrated sensor noise below the band
    and the white noise above it, and with them the unknown states at the window's start.

    ``weighting="eiv"`` (needs ``filter``; errors in variables): the mean squared residual divided by
    (1, p1, p2) G (1, p1, p2)^T (``noise_gram``), the variance per unit noise variance that white sensor noise
    gives the filtered residual at this p. Noise in the regressors adds sigma^2 times that term to the expected
    squared residual, which pulls the plain fit towards p of little noise gain (attenuation bias); after the
    division the expectation is misfit / g(p) + sigma^2, least at the true p whatever sigma, so no noise level
    is needed (the total-least-squares idea).

    ``target`` (docs/label_free.md): ``residual`` fits p to the residual as above. On clean, consistent windows the
    residual is (p - p*) . (rel_vel, rel_disp), so the loss is dp^T G dp with G the regressors' 2 x 2 Gram
    matrix, and G makes a relative error in p2 cost about a hundred times what the same error in p1 costs: the
    network learns p1 poorly. ``least_squares`` takes the minimiser of the same residual per window instead,
    p_ls = G^-1 b (float64, no gradient through it, a relative ridge RIDGE), and fits p to it as the
    labelled objective fits p to the labels: mean L1 of (p - p_ls) / ``p_scale``, equal weight for both. Still
    no labels: p_ls comes from the signals alone. ``whitened``: (p - p_ls) / p_scale in the metric of the
    regressors' correlation (G scaled to a unit diagonal), which keeps their coupling and drops their scales.
    """

    uses_labels = False
    monitor = LABEL_FREE
    fir: np.ndarray | None = None  # the band-pass taps (float64) with a filter (set below)
    outside_fir = None

    def __init__(
        self,
        normalize: bool = True,
        filter: dict | None = None,
        weighting: str = "none",
        dt: float | None = None,
        measurement: str = "consistent",
        target: str = "residual",
        p_scale: Sequence[float] | None = None,
    ):
        super().__init__()
        checked = arguments.hybrid(normalize, filter, weighting, dt, measurement, target, p_scale)
        self.target = target
        if checked.p_scale is not None:
            self.register_buffer("p_scale", torch.tensor(checked.p_scale))
        self.normalize = bool(normalize)
        self.filter, self.weighting, self.fir = checked.filter, weighting, checked.fir
        self.keys = ("seat_f", "rel_vel_f", "rel_disp_f") if filter is not None else ("rel_vel", "rel_disp")
        # the band-pass taps the data module filters the batches with (hybrid_sysid.training.build), so the
        # batches always carry what this objective reads
        if weighting == "eiv":
            self.register_buffer("gram", torch.tensor(noise_gram(self.fir, dt, measurement), dtype=torch.float32))

    def forward(self, pred: torch.Tensor, batch: dict) -> torch.Tensor:
        if self.filter is not None:
            if "seat_f" not in batch:
                raise KeyError(
                    "the objective has a filter but the batch has no filtered signals: build the data "
                    "module with the objective's fir (hybrid_sysid.training.build.build_datamodule does)"
                )
            seat, rel_vel, rel_disp = (batch[k].to(pred) for k in self.keys)
        else:
            seat = batch["signals"][:, 0].to(pred)
            rel_vel, rel_disp = (batch[k].to(pred) for k in self.keys)
        if self.target != "residual":
            return self._to_least_squares(pred, seat, rel_vel, rel_disp)
        z_rec = -pred[:, :1] * rel_vel - pred[:, 1:2] * rel_disp
        mse = (seat - z_rec).pow(2).mean(dim=1)
        if self.weighting == "eiv":
            p = torch.cat([torch.ones_like(pred[:, :1]), pred], dim=1)
            mse = mse / torch.einsum("bi,ij,bj->b", p, self.gram, p)
        if self.normalize:
            mse = mse / (seat.pow(2).mean(dim=1) + EPS)
        return mse.mean()

    def _to_least_squares(self, pred, seat, rel_vel, rel_disp) -> torch.Tensor:
        p_ls, gram = least_squares_target(seat, rel_vel, rel_disp)
        err = (pred - p_ls.to(pred)) / self.p_scale
        if self.target == "least_squares":
            return err.abs().sum(dim=1).mean()
        d = gram.diagonal(dim1=1, dim2=2).sqrt()
        corr = (gram / (d[:, :, None] * d[:, None, :])).to(pred)
        return torch.einsum("bi,bij,bj->b", err, corr, err).mean()


@torch.no_grad()
def least_squares_target(seat, rel_vel, rel_disp, ridge: float = RIDGE) -> tuple[torch.Tensor, torch.Tensor]:
    """Per window, the p that minimises the residual seat + p1 rel_vel + p2 rel_disp over the window, in float64:
    (p_ls (B, 2), G (B, 2, 2)), G = A^T A with A = (rel_vel, rel_disp), p_ls = -G^-1 A^T seat. G's diagonal grows
    by ``ridge`` times itself (a ridge in each regressor's own scale, which differ about a thousandfold), so a
    window of no motion stays finite."""
    a = torch.stack([rel_vel, rel_disp], dim=2).double()  # (B, W, 2)
    gram = a.transpose(1, 2) @ a
    b = -(a.transpose(1, 2) @ seat.double().unsqueeze(2))
    shift = torch.diag_embed(ridge * gram.diagonal(dim1=1, dim2=2) + torch.finfo(torch.float64).tiny)
    return torch.linalg.solve(gram + shift, b).squeeze(2), gram


class CombinedObjective(nn.Module):
    """labelled_weight * J_L + hybrid_weight * J_U; other keyword arguments go to the two objectives."""

    # what the interface asks of the class (model.base.Objective); an instance sets its own from its weights
    uses_labels = True
    monitor = LABELLED
    fir: np.ndarray | None = None
    outside_fir = None

    def __init__(
        self,
        p_scale: Sequence[float],
        labelled_weight: float = 1.0,
        hybrid_weight: float = 1.0,
        normalize: bool = True,
        filter: dict | None = None,
        weighting: str = "none",
        dt: float | None = None,
        measurement: str = "consistent",
    ):
        super().__init__()
        arguments.combined(p_scale, labelled_weight, hybrid_weight, normalize, filter, weighting, dt, measurement)
        self.labelled_weight, self.hybrid_weight = float(labelled_weight), float(hybrid_weight)
        self.labelled = LabelledObjective(p_scale=p_scale)
        self.hybrid = HybridObjective(
            normalize=normalize, filter=filter, weighting=weighting, dt=dt, measurement=measurement
        )
        # with labelled_weight 0 the combination is label-free, and model selection must stay so too
        self.uses_labels = self.labelled_weight > 0
        self.monitor = LABELLED if self.uses_labels else LABEL_FREE
        self.fir = self.hybrid.fir

    def forward(self, pred: torch.Tensor, batch: dict) -> torch.Tensor:
        # a zero weight skips its term, so a hybrid-only combination still never reads the labels
        loss = pred.new_zeros(())
        if self.labelled_weight:
            loss = loss + self.labelled_weight * self.labelled(pred, batch)
        if self.hybrid_weight:
            loss = loss + self.hybrid_weight * self.hybrid(pred, batch)
        return loss
