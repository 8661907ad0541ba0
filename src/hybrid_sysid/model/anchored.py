"""An estimator anchored in physics: the window's own fit of the seat, trusted as far as the fit itself says it may
be, and a network for the rest (docs/design.md, "The anchored estimator").

Per window and parameter, p = w p_fit + (1 - w) p_net with w = tau^2 / (tau^2 + se^2): se is the fit's own
relative standard error, and the network gives both p_net and tau from the window and the fit's statistics. The
fit (``anchor``) is the errors-in-variables maximum likelihood (baselines.errors_in_variables) or the band-passed
least squares (physics.seat_fit).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import torch
from torch import nn

from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.core.checks import bad, check_choice, check_number
from hybrid_sysid.core.options import FIXES, MEASUREMENTS
from hybrid_sysid.data.spec import MIN_FILTERED
from hybrid_sysid.model.networks import FastCNN
from hybrid_sysid.physics.filters import filter_taps
from hybrid_sysid.physics.seat_fit import SeatFit, fit_windows

# the least-squares baseline's band (conf/baseline/ls_bandpass.yaml): it keeps the seat resonance and drops the drift
# of integrated noise below it and the white noise above it
DEFAULT_FILTER = {"low_hz": 4.0, "high_hz": 20.0, "taps": 151}
N_STATS = 8  # what the head reads of the fit: log p (2), log se (2), unexplained share, correlation, valid (2)
ANCHORS = ("eiv", "ls")


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
    fix: the classical fix of the fault the config simulates (``${fault_fix:}``, core.options.FIXES), handed to
        the errors-in-variables fit as its ``fix`` when it is not "none"; the least-squares anchor ignores it.

    The head reads the pooled features of the window, log p and log se of the anchor, and the least-squares fit's
    unexplained share and regressor correlation (``physics.seat_fit.SeatFit``), so p_net can also learn what is
    left of the fit's error from how much of the seat it explains.
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
        **cnn,
    ):
        super().__init__(p_min, p_max, **cnn)
        check_choice("measurement", measurement, MEASUREMENTS)
        check_choice("anchor", anchor, ANCHORS)
        check_choice("fix", fix, FIXES)
        check_number("tau_min", tau_min, 0, 1, low_open=True)
        if not (isinstance(tau_max, (int, float)) and tau_min < tau_max <= 10):
            bad("tau_max", tau_max, f"must lie in (tau_min = {tau_min:g}, 10]")
        band = dict(DEFAULT_FILTER if filter is None else filter)
        self.fir = filter_taps(band, dt)
        self.dt, self.measurement = float(dt), measurement
        self.anchor_kind, self.fix = anchor, fix
        self.eiv = None
        if anchor == "eiv":
            # a fault's fix only when there is one, so a clean config needs nothing of the fit beyond its band
            extra = {} if fix == "none" else {"fix": fix}
            self.eiv = ErrorsInVariablesFit(noise_ratio=1.0, dt=self.dt, **band, **extra)
        self.log_tau = (math.log(tau_min), math.log(tau_max) - math.log(tau_min))
        width = self.head.in_features
        self.head = nn.Sequential(nn.Linear(width + N_STATS, width), nn.ReLU(), nn.Linear(width, 4))

    @staticmethod
    def window_bounds(n_layers: int = 4, filter: dict | None = None, **arguments) -> tuple[int, None]:
        """Long enough for the trunk and for the band-pass to leave MIN_FILTERED samples to fit."""
        taps = (DEFAULT_FILTER if filter is None else filter).get("taps", DEFAULT_FILTER["taps"])
        return max(2 ** int(n_layers), int(taps) + MIN_FILTERED - 1), None

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

    def forward(self, signals: torch.Tensor) -> torch.Tensor:
        fit = self.anchor(signals)
        p_fit, se = (torch.from_numpy(a).to(signals) for a in (fit.p, fit.se))
        valid = torch.isfinite(p_fit) & (p_fit > 0)
        mid = self.log_lo + self.log_span / 2  # the centre of the head's range, in log p
        ratio = torch.where(valid, torch.log(p_fit.clamp_min(1e-30)) - mid, 0.0).clamp(-4, 4)
        log_se = torch.where(valid, torch.log10(se.clamp_min(1e-12)), 1.0).clamp(-8, 1) / 4
        unexplained = torch.from_numpy(np.log10(np.clip(fit.unexplained, 1e-12, 1.0)) / 6).to(signals)
        rho = torch.from_numpy(fit.correlation).to(signals)
        stats = torch.cat([ratio, log_se, unexplained[:, None], rho[:, None], valid.to(signals)], dim=1)
        out = self.head(torch.cat([self.embed(signals), stats], dim=1))
        p_net = self.bounded(out[:, :2])
        tau = torch.exp(self.log_tau[0] + self.log_tau[1] * torch.sigmoid(out[:, 2:]))
        w = torch.where(valid, tau.pow(2) / (tau.pow(2) + se.pow(2)), 0.0)
        return w * torch.where(valid, p_fit, p_net) + (1 - w) * p_net
