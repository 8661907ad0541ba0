"""An estimator anchored in physics: the window's own fit of the seat, trusted as far as the fit itself says it may
be, and a network for the rest (docs/anchored.md, "The anchored estimator").

Per window and parameter, p = w p_fit + (1 - w) p_net with w = tau^2 / (tau^2 + se^2): se is the fit's own
relative standard error, and the network gives both p_net and tau from the window and the fit's statistics. The
fit (``anchor``) is the errors-in-variables maximum likelihood (baselines.errors_in_variables) or the band-passed
least squares (physics.seat_fit). With a ``prior``, p_net is the window's MAP fit times a learned factor; with
``blend`` too, the evaluated output is p^g times the window's Bayes estimate^(1 - g) (baselines.eiv_bayes).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import torch
from torch import nn

from hybrid_sysid.model import arguments
from hybrid_sysid.model.networks import FastCNN
from hybrid_sysid.physics.seat_fit import SeatFit, fit_windows

N_STATS = 8  # what the head reads of the fit: log p (2), log se (2), unexplained share, correlation, valid (2)
N_PRIOR_STATS = 5  # and of the MAP fit, with a prior: log p (2), log se (2), valid
# the partner's share before training: 0.12 at noise 0.1, 0.001 at 0.01 (a = -2, softplus(1.8546) = 2)
SIGMA_REF, MIX_INIT = 0.1, (-2.0, 1.8546)
MAX_FACTOR = 2.0  # |log| of the factor the network may put on the MAP fit: a correction, not a new estimate


class AnchoredCNN(FastCNN):
    """FastCNN's trunk and bounded head, gated against the window's own fit of the seat.

    Why the gate has this form: with se the fit's relative standard error and tau the network's own typical
    error, w = tau^2 / (tau^2 + se^2) is the inverse-variance weight of two independent estimates. Where the seat
    equation holds and the window is informative, se is rounding (about 1e-6 on float32 signals), so w is 1 to
    about 1e-6 and p is the fit's p before any training; tau >= ``tau_min`` keeps that true whatever the weights.
    Under noise or a recording fault the fit's residual grows, se with it, and the network takes over as far as
    the training objective finds it better. The fit is computed in float64 numpy, without gradient: it has no
    weights. A fit that is not defined or not positive gives w = 0.

    anchor: "eiv", the errors-in-variables maximum likelihood with equal noise on both channels
        (``ErrorsInVariablesFit``, started from the band-passed least squares), or "ls", that least-squares fit
        itself. Least squares takes the body channel as exact, so under noise its p is biased towards zero, and
        its se, from a band-passed and so coloured residual, ranks fits rather than measuring their error. The
        likelihood fit reaches the Cramer-Rao bound and its se follows its actual spread at a good signal-to-noise
        ratio (physics/eiv/), which is what the gate's weight assumes. The constructor's default is "ls": a
        saved config written before the argument existed was trained with it. conf/model/anchored.yaml sets
        "eiv".
    fix: the classical fix of the fault the config simulates (``${fault_fix:}``, physics.faults.fixes), handed to
        the errors-in-variables fit as its ``fix`` when it is not "none"; the least-squares anchor ignores it.

    prior: None, or the simulator's draws of the seat as the MAP baseline takes them (``PRIOR_KEYS``; conf/model/
        anchored.yaml fills it from the data and car sections). Then p_net = p_map exp(delta): the window's MAP
        fit (``ErrorsInVariablesFit`` with that prior and the fix) times a factor the head learns, |delta| <=
        log ``MAX_FACTOR``, 0 before training (the last layer starts at zero). Where the data leave p loose the
        prior decides the MAP fit, and the network only corrects it; where they do not, the gate keeps the
        likelihood fit. A network that learns p_net from scratch has to rediscover the prior from its
        objective; a label-free objective's targets carry noise as large as the window's own error at noise
        0.03, and the network then missed the MAP fit it could have started from (docs/anchored.md).
    blend: None, or g in [0, 1]: in evaluation (not in training), p^g p_bayes^(1 - g), p_bayes the window's Bayes
        estimate (``ErrorsInVariablesBayes``: the likelihood times the simulator's exact prior). Both estimate p
        from the same window, but their errors are partly independent: the Bayes estimate is the best the window's
        likelihood and the prior allow, and the network adds what a label-free objective teaches of the rest (the
        input's statistics, say). Only where that estimate is defined: with a prior whose seat_spread > 0 (at 0
        the prior has no density) and no fault fix (the likelihood then has a third parameter); elsewhere, and
        where the window's Bayes estimate is not finite, p is kept. Training steps never see it: it has no
        weights, and a Bayes fit costs about 4 ms a window (0.25 s a step of 64). Validation, in evaluation mode,
        scores the blend, so the checkpoint kept is the best blended one.
    partner: True: a second estimate, FastCNN's bounded head on the trunk's features, trained by the same objective
        on its own (``auxiliary``, model.module) and mixed in by a share that grows with the window's noise (the
        likelihood fit's sigma, scaled by 1 - w): p^(1 - m) p_partner^m (``mixed``). A fit-free network is the better
        estimate at noise 0.1 and the worse below 0.03 (docs/results_notes.md); the share lets each lead where it
        is better, and keeps clean windows exact.
    trunk: False: the head reads the fits' statistics alone, without the convolutional trunk's features of the
        window (with a prior, those statistics hold what the trunk found, at a fraction of a step's cost).

    The head reads the pooled features of the window, log p and log se of the anchor, and the least-squares fit's
    unexplained share and regressor correlation (``physics.seat_fit.SeatFit``), so p_net can also learn what is
    left of the fit's error from how much of the seat it explains; with a prior, also the MAP fit's log p and se.
    """

    prior_arguments = ("p_min", "p_max")

    def __init__(
        self,
        p_min: Sequence[float],
        p_max: Sequence[float],
        dt: float,
        measurement: str = "consistent",
        filter: dict | None = None,
        tau_min: float = 1e-3,
        tau_max: float = 1.0,
        anchor: str = "ls",
        fix: str = "none",
        prior: dict | None = None,
        trunk: bool = True,
        blend: float | None = None,
        partner: bool = False,
        **cnn,
    ):
        super().__init__(p_min, p_max, **cnn)
        checked = arguments.anchored(
            p_min, p_max, dt, measurement, filter, tau_min, tau_max, anchor, fix, prior, trunk, blend, partner, **cnn
        )
        self.fir, self.dt, self.measurement = checked.fir, float(dt), measurement
        self.anchor_kind, self.fix = anchor, fix
        self.eiv, self.map, self.bayes, self.blend = checked.eiv, checked.map, checked.bayes, checked.blend
        self.trunk = trunk
        self.partner, self.auxiliary = partner, ()
        if partner:  # its own head on the trunk's features, and (a, b) of the share (``mixed``)
            self.partner_head = nn.Linear(self.head.in_features, 2)
            self.mix = nn.Parameter(torch.tensor(MIX_INIT))
        if not trunk and not partner:  # no parameters that nothing reads (weight decay, DDP's unused-parameter check)
            self.features = nn.Sequential()
        self.log_tau = (math.log(tau_min), math.log(tau_max) - math.log(tau_min))
        width = self.head.in_features
        n_in = (width if trunk else 0) + N_STATS + (0 if prior is None else N_PRIOR_STATS)
        self.head = nn.Sequential(nn.Linear(n_in, width), nn.ReLU(), nn.Linear(width, 4))
        if prior is not None:  # p_net starts as the MAP fit itself
            nn.init.zeros_(self.head[-1].weight)
            nn.init.zeros_(self.head[-1].bias)

    window_bounds = staticmethod(arguments.anchored_window)

    def output_bounds(self) -> None:
        """None: the fit's part is not bounded by the head."""
        return None

    def anchor(self, signals: torch.Tensor) -> SeatFit:
        """The fit of each window (B, 2, W), in float64 numpy: p and se of the anchor, the unexplained share and
        the correlation of the band-passed least squares."""
        x = signals.detach().to("cpu", torch.float64).numpy()
        fit = fit_windows(x[:, 0], x[:, 1], self.dt, self.measurement, self.fir)
        if self.eiv is None:
            return fit
        p, se = self.eiv.fit_windows(x[:, 0], x[:, 1], self.dt, self.measurement, guarded=True)
        return SeatFit(p, se, fit.unexplained, fit.correlation)

    def fits(self, signals: torch.Tensor) -> tuple[SeatFit, tuple[np.ndarray, np.ndarray] | None]:
        """The anchor's fit of each window (``anchor``) and, with a prior, the MAP fit's (p, se) (B, 2) (NaN p where
        not defined); with a prior, the likelihood is solved once for the anchor, the MAP fit and the blend."""
        return self._fits(signals)[:2]

    def _fits(self, signals: torch.Tensor):
        """``fits`` and, with a prior, the windows in float64 and the raw MAP fit (for ``blended``)."""
        if self.map is None:
            return self.anchor(signals), None, None
        x = signals.detach().to("cpu", torch.float64).numpy()
        # the likelihood's start is the anchor's band-passed least squares, so an LS anchor is fitted once too
        start, ml, map_fit, raw = self.map.fit_with_ml(x[:, 0], x[:, 1], self.dt, self.measurement)
        fit = start if self.eiv is None else SeatFit(*ml, start.unexplained, start.correlation)
        return fit, map_fit, (x, raw)

    def _stats(self, p, se):
        """log p about the head's centre, log10 se, and where p is defined and positive."""
        valid = torch.isfinite(p) & (p > 0)
        mid = self.log_lo + self.log_span / 2  # the centre of the head's range, in log p
        ratio = torch.where(valid, torch.log(p.clamp_min(1e-30)) - mid, 0.0).clamp(-4, 4)
        log_se = torch.where(valid & ~torch.isnan(se), torch.log10(se.clamp_min(1e-12)), 1.0).clamp(-8, 1) / 4
        return ratio, log_se, valid

    def forward(self, signals: torch.Tensor) -> torch.Tensor:
        fit, map_fit, raw = self._fits(signals)
        p_fit, se = (torch.from_numpy(a).to(signals) for a in (fit.p, fit.se))
        ratio, log_se, valid = self._stats(p_fit, se)
        unexplained = torch.from_numpy(np.log10(np.clip(fit.unexplained, 1e-12, 1.0)) / 6).to(signals)
        rho = torch.from_numpy(fit.correlation).to(signals)
        parts = [ratio, log_se, unexplained[:, None], rho[:, None], valid.to(signals)]
        if self.map is not None:
            p_map, se_map = (torch.from_numpy(a).to(signals) for a in map_fit)
            map_ratio, map_log_se, map_valid = self._stats(p_map, se_map)
            map_valid = map_valid.all(dim=1, keepdim=True)
            parts += [map_ratio, map_log_se, map_valid.to(signals)]
        features = self.embed(signals) if self.trunk or self.partner else None
        if self.trunk:
            parts.insert(0, features)
        out = self.head(torch.cat(parts, dim=1))
        p_net = self.bounded(out[:, :2])
        if self.map is not None:
            delta = math.log(MAX_FACTOR) * torch.tanh(out[:, :2])
            # NaN in the branch torch.where drops would still reach the gradient as 0 * NaN
            p_map = torch.where(map_valid, p_map, 1.0)
            p_net = torch.where(map_valid, p_map * torch.exp(delta), p_net)
        tau = torch.exp(self.log_tau[0] + self.log_tau[1] * torch.sigmoid(out[:, 2:]))
        w = torch.where(valid, tau.pow(2) / (tau.pow(2) + se.pow(2)), 0.0)
        p = w * torch.where(valid, p_fit, p_net) + (1 - w) * p_net
        if self.bayes is not None and not self.training:
            p = self.blended(p, *raw)
        return p if not self.partner else self.mixed(p, features, raw[1][2], w)

    def mixed(self, p: torch.Tensor, features: torch.Tensor, out, gate: torch.Tensor) -> torch.Tensor:
        """p^(1 - m) p_partner^m, m = (1 - gate) sigmoid(a + softplus(b) (log sigma - log SIGMA_REF)), sigma the seat
        noise the window's likelihood fit estimates (out: its EivFit); p where sigma or either p is not defined.
        gate: the fit's weight w, 1 to about 1e-6 on a clean window, whose exact fit the partner so leaves alone
        whatever a and b became."""
        p_partner = self.bounded(self.partner_head(features))
        self.auxiliary = (p_partner,) if self.training else ()  # trained on its own too (model.module)
        sigma = torch.from_numpy(np.sqrt(out.ml.sigma2)).to(p)[:, None]
        ok = torch.isfinite(sigma) & (sigma > 0) & torch.isfinite(p) & (p > 0)
        # the slope through softplus: the share grows with the noise, so clean windows keep the exact fit
        slope = nn.functional.softplus(self.mix[1])
        logit = self.mix[0] + slope * (torch.log(sigma.where(ok, SIGMA_REF)) - math.log(SIGMA_REF))
        m = (1 - gate) * torch.sigmoid(logit)
        mixed = torch.exp((1 - m) * torch.log(p.where(ok, 1.0)) + m * torch.log(p_partner))
        return torch.where(ok, mixed, p)

    def blended(self, p: torch.Tensor, x: np.ndarray, raw: tuple) -> torch.Tensor:
        """p^g p_bayes^(1 - g) per window and parameter (g = ``blend``), the mean of the two in log p; p where
        either is not finite and positive. x: the windows (B, 2, W) in float64; raw: the MAP fit of ``_fits``."""
        p_bayes, _ = self.bayes.from_fit(x[:, 0], x[:, 1], self.dt, self.measurement, *raw)
        p_bayes = torch.from_numpy(p_bayes).to(p)
        ok = torch.isfinite(p_bayes) & (p_bayes > 0) & torch.isfinite(p) & (p > 0)
        log_mix = self.blend * torch.log(p.clamp_min(1e-30)) + (1 - self.blend) * torch.log(p_bayes.where(ok, 1.0))
        mixed = torch.exp(log_mix)
        return torch.where(ok, mixed, p)
