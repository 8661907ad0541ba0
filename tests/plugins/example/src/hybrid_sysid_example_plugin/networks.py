"""A small network, as a plugin: two convolutions, a mean over time, and a head bounded to the prior of p."""

import torch
from torch import nn


class TinyNet(nn.Module):
    prior_arguments = ("p_min", "p_max")  # carry the prior of p, not the architecture: weights load across priors

    def __init__(self, p_min, p_max, channels: int = 8):
        super().__init__()
        self.register_buffer("log_lo", torch.tensor(p_min, dtype=torch.float32).log())
        self.register_buffer("log_hi", torch.tensor(p_max, dtype=torch.float32).log())
        self.features = nn.Sequential(
            nn.Conv1d(2, channels, 9, stride=2), nn.ReLU(), nn.Conv1d(channels, channels, 9, stride=2), nn.ReLU()
        )
        self.head = nn.Linear(channels, 2)

    @staticmethod
    def window_bounds(**arguments):
        return 25, None  # (shortest, longest or None): two kernel-9, stride-2 convolutions need 25 steps

    def output_bounds(self):  # (low, high) arrays of 2, or None for an unbounded head
        return self.log_lo.exp().double().cpu().numpy(), self.log_hi.exp().double().cpu().numpy()

    def forward(self, signals):  # (B, 2, W): seat z'', body y'' in m/s^2 -> (B, 2) positive p
        h = self.features(signals).mean(dim=-1)
        return torch.exp(self.log_lo + (self.log_hi - self.log_lo) * torch.sigmoid(self.head(h)))
