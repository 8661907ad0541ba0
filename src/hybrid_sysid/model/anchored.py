"""An estimator anchored in physics: the window's band-passed least-squares p, trusted as far as the fit itself
says it may be, and a network for the rest (docs/design.md, "The anchored estimator").

Per window and parameter, p = w p_ls + (1 - w) p_net with w = tau^2 / (tau^2 + se^2): se is the fit's own
relative standard error, and the network gives both p_net and tau from the window and the fit's statistics.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import torch
from torch import nn

from hybrid_sysid.core.checks import bad, check_choice, check_number
from hybrid_sysid.core.options import MEASUREMENTS
from hybrid_sysid.data.spec import MIN_FILTERED
from hybrid_sysid.model.networks import FastCNN
from hybrid_sysid.physics.filters import filter_taps
from hybrid_sysid.physics.seat_fit import SeatFit, fit_windows

# the least-squares baseline's band (conf/baseline/ls_bandpass.yaml): it keeps the seat resonance and drops the drift
# of integrated noise below it and the white noise above it
DEFAULT_FILTER = {"low_hz": 4.0, "high_hz": 20.0, "taps": 151}
N_STATS = 8  # what the head reads of the fit: log p_ls (2), log se (2), unexplained share, correlation, valid (2)


class AnchoredCNN(FastCNN):
    """FastCNN's trunk and bounded head, gated against the window's band-passed least-squares fit.

    Why the gate has this form: with se the fit's relative standard error and tau the network's own typical
    error, w = tau^2 / (tau^2 + se^2) is the inverse-variance weight of two independent estimates. Where the seat
    equation holds and the window is informative, se is rounding (about 1e-6 on float32 signals), so w is 1 to
    about 1e-6 and p is the fit's p before any training; tau >= ``tau_min`` keeps that true whatever the weights.
    Under noise or a recording fault the fit's residual grows, se with it, and the network takes over as far as
    the training objective finds it better. The fit is computed in float64 numpy, without gradient: it has no
    weights. A fit that is not defined or not positive gives w = 0.

    The head reads the pooled features of the window and the fit's statistics (``physics.seat_fit.SeatFit``), so
    p_net can also learn the fit's bias under noise (errors in variables) from how much of the seat it explains.
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
        **cnn,
    ):
        super().__init__(p_min, p_max, **cnn)
        check_choice("measurement", measurement, MEASUREMENTS)
        check_number("tau_min", tau_min, 0, 1, low_open=True)
        if not (isinstance(tau_max, (int, float)) and tau_min < tau_max <= 10):
            bad("tau_max", tau_max, f"must lie in (tau_min = {tau_min:g}, 10]")
        self.fir = filter_taps(dict(DEFAULT_FILTER if filter is None else filter), dt)
        self.dt, self.measurement = float(dt), measurement
        self.log_tau = (math.log(tau_min), math.log(tau_max) - math.log(tau_min))
        width = self.head.in_features
        self.head = nn.Sequential(nn.Linear(width + N_STATS, width), nn.ReLU(), nn.Linear(width, 4))

    @staticmethod
    def window_bounds(n_layers: int = 4, filter: dict | None = None, **arguments) -> tuple[int, None]:
        """Long enough for the trunk and for the band-pass to leave MIN_FILTERED samples to fit."""
        taps = (DEFAULT_FILTER if filter is None else filter).get("taps", DEFAULT_FILTER["taps"])
        return max(2 ** int(n_layers), int(taps) + MIN_FILTERED - 1), None

    def output_bounds(self) -> None:
        """None: the least-squares part is not bounded by the head."""
        return None

    def anchor(self, signals: torch.Tensor) -> SeatFit:
        """The band-passed least-squares fit of each window (B, 2, W), in float64 numpy."""
        x = signals.detach().to("cpu", torch.float64).numpy()
        return fit_windows(x[:, 0], x[:, 1], self.dt, self.measurement, self.fir)

    def forward(self, signals: torch.Tensor) -> torch.Tensor:
        fit = self.anchor(signals)
        p_ls, se = (torch.from_numpy(a).to(signals) for a in (fit.p, fit.se))
        valid = torch.isfinite(p_ls) & (p_ls > 0)
        mid = self.log_lo + self.log_span / 2  # the centre of the head's range, in log p
        ratio = torch.where(valid, torch.log(p_ls.clamp_min(1e-30)) - mid, 0.0).clamp(-4, 4)
        log_se = torch.where(valid, torch.log10(se.clamp_min(1e-12)), 1.0).clamp(-8, 1) / 4
        unexplained = torch.from_numpy(np.log10(np.clip(fit.unexplained, 1e-12, 1.0)) / 6).to(signals)
        rho = torch.from_numpy(fit.correlation).to(signals)
        stats = torch.cat([ratio, log_se, unexplained[:, None], rho[:, None], valid.to(signals)], dim=1)
        out = self.head(torch.cat([self.embed(signals), stats], dim=1))
        p_net = self.bounded(out[:, :2])
        tau = torch.exp(self.log_tau[0] + self.log_tau[1] * torch.sigmoid(out[:, 2:]))
        w = torch.where(valid, tau.pow(2) / (tau.pow(2) + se.pow(2)), 0.0)
        return w * torch.where(valid, p_ls, p_net) + (1 - w) * p_net
