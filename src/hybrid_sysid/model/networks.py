"""The two parameter estimators: the paper's CNN (sec. 2.4) and a compact CNN that learns in minutes on a CPU.

Both map a batch of sensor windows (B, 2, W) -- channel 0 seat z'', channel 1 body y'' -- to (B, 2) positive
predictions (p1, p2) in physical units (1/s, 1/s^2), so every objective sees the same thing. Both are told the
prior of p = (C3, K3) / m3 (the car's and the seat masses' range): the run's config derives it
(``${p_prior:...}``, hybrid_sysid.config), so another car or mass range moves it too.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from torch import nn

from hybrid_sysid.core.options import ACTIVATIONS
from hybrid_sysid.model import arguments


class PaperCNN(nn.Module):
    """The paper's network: Conv1d(100, k=50) tanh, Conv1d(100, k=10), flatten, dense 100, 10, 2, |.|.

    The paper names tanh only after the first convolution. ``activation`` (default tanh) is put after the
    second convolution and after the dense 100 and 10 layers: without it, conv2 -> dense 100 -> 10 -> 2 collapse
    into a single linear map and the extra layers would be pointless; tanh is the paper's only named activation.
    ``activation="none"`` gives the literal reading. The abs output is multiplied by a fixed label scale
    ``p_scale`` (a buffer; the midpoint of the prior), so the raw outputs are of order 1: an abs(linear) head from
    random weights otherwise needs very many steps just to reach p2 ~ 1000 (docs/physics.md, "Choices the paper
    leaves open").
    """

    prior_arguments = ("p_scale",)
    SHORTEST = arguments.PAPER_SHORTEST

    def __init__(self, p_scale: Sequence[float], window: int = 500, activation: str = "tanh"):
        super().__init__()
        window, p_scale, flat = arguments.paper_cnn(p_scale, window, activation)
        self.register_buffer("p_scale", torch.tensor(p_scale))
        act = getattr(nn, ACTIVATIONS[activation])
        self.net = nn.Sequential(
            nn.Conv1d(2, 100, kernel_size=50),  # seat, body
            nn.Tanh(),
            nn.Conv1d(100, 100, kernel_size=10),
            act(),
            nn.Flatten(),
            nn.Linear(flat, 100),
            act(),
            nn.Linear(100, 10),
            act(),
            nn.Linear(10, 2),
        )

    window_bounds = staticmethod(arguments.paper_cnn_window)

    def output_bounds(self) -> None:
        """None: the absolute-value head is unbounded."""
        return None

    def forward(self, signals: torch.Tensor) -> torch.Tensor:
        return self.net(signals).abs() * self.p_scale


class FastCNN(nn.Module):
    """A compact 1D CNN: n_layers x [Conv1d stride 2, BatchNorm, ReLU], global average pooling, linear head.

    Input conditioning, because the raw accelerations span ~16x in amplitude between road classes A and E:
    each window is divided by its body channel's RMS (the seat/body ratio, which carries p, is kept), and the
    seat-minus-body difference is added as a third channel (the relative motion that the seat spring and
    damper act on). The head is bounded: log p = log p_lo + (log p_hi - log p_lo) sigmoid(h), with the prior
    [p_min, p_max] widened by ``margin`` (as a fraction of the log range) on each side so the true extremes are
    not at the sigmoid's flat ends. A bounded head starts every prediction inside the prior, which keeps the
    hybrid objective sane from step 0; log scaling matches p ~ 1/m3 and the relative-deviation metric.

    The network reads two channels, seat and body (the difference needs both).

    The defaults (32 channels, kernel 9) were chosen for accuracy per CPU second of training on data=default:
    more channels cost more per step than they gained. ``downsample="stride"`` (a stride-2 convolution) halves
    the sequence in each layer instead of a stride-1 convolution followed by MaxPool(2) (``"pool"``): it computes
    half the convolution outputs and skips max pooling, so a step costs less, and although it learns a little
    less per step it is ahead per second of training. BatchNorm, ReLU, max and mean pooling are deterministic
    on the CPU. ``bn_momentum`` 0.01 (torch's default is 0.1) averages the running statistics over ~100
    batches, so the eval-mode statistics, and with them the test error, do not follow the last few training
    batches.
    """

    prior_arguments = ("p_min", "p_max")

    def __init__(
        self,
        p_min: Sequence[float],
        p_max: Sequence[float],
        channels: int = 32,
        n_layers: int = 4,
        kernel_size: int = 9,
        margin: float = 0.1,
        bn_momentum: float = 0.01,
        downsample: str = "stride",
    ):
        super().__init__()
        channels, n_layers, kernel_size, lo, hi = arguments.fast_cnn(
            p_min, p_max, channels, n_layers, kernel_size, margin, bn_momentum, downsample
        )
        log_lo, log_hi = torch.tensor(lo).log(), torch.tensor(hi).log()
        pad = margin * (log_hi - log_lo)
        self.register_buffer("log_lo", log_lo - pad)
        self.register_buffer("log_span", (log_hi - log_lo) + 2 * pad)

        layers, c_in = [], 3  # seat, body and their difference
        stride = 2 if downsample == "stride" else 1
        for _ in range(n_layers):
            layers += [
                nn.Conv1d(c_in, channels, kernel_size, stride=stride, padding=kernel_size // 2, bias=False),
                nn.BatchNorm1d(channels, momentum=bn_momentum),
                nn.ReLU(),
            ]
            if downsample == "pool":
                layers.append(nn.MaxPool1d(2))
            c_in = channels
        self.features = nn.Sequential(*layers)
        self.head = nn.Linear(channels, 2)

    window_bounds = staticmethod(arguments.fast_cnn_window)

    def output_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The head's range: the prior widened by ``margin`` (its buffers, so a loaded network's own)."""
        log_lo, log_span = self.log_lo.double().cpu().numpy(), self.log_span.double().cpu().numpy()
        return np.exp(log_lo), np.exp(log_lo + log_span)

    def embed(self, signals: torch.Tensor) -> torch.Tensor:
        """(B, channels): the pooled features the head reads."""
        # per-window scale from the body channel; the floor only guards an all-zero (parked) window
        rms = signals[:, 1:2].pow(2).mean(dim=-1, keepdim=True).sqrt().clamp_min(1e-8)
        x = signals / rms
        x = torch.cat([x, x[:, :1] - x[:, 1:2]], dim=1)
        return self.features(x).mean(dim=-1)

    def bounded(self, logits: torch.Tensor) -> torch.Tensor:
        """p in the head's range from unbounded logits (B, 2): log p = log_lo + log_span sigmoid(logits)."""
        return torch.exp(self.log_lo + self.log_span * torch.sigmoid(logits))

    def forward(self, signals: torch.Tensor) -> torch.Tensor:
        return self.bounded(self.head(self.embed(signals)))
