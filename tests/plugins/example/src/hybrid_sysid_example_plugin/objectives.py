"""The squared relative error of p: a labelled objective, as a plugin."""

import torch
from torch import nn


class RelativeL2Objective(nn.Module):
    uses_labels = True  # reads batch["params"]
    fir = None  # no band-pass: the batches carry no filtered signals
    outside_fir = None  # no fit over the rest of the recording: the batches carry no p_out
    monitor = "val/rel_dev"  # the figure model selection watches (a label-free objective: "val/loss")

    def __init__(self, p2_weight: float = 1.0):
        super().__init__()
        if not p2_weight > 0:
            raise ValueError(f"p2_weight = {p2_weight} must be positive")
        self.register_buffer("weights", torch.tensor([1.0, p2_weight]))
        # training batches scored, saved with the weights: which objective trained a run, read from its checkpoint
        self.register_buffer("scored", torch.zeros((), dtype=torch.long))

    def forward(self, pred, batch):  # pred (B, 2) p in 1/s, 1/s^2; batch["params"] (B, 2) true p
        true = batch["params"].to(pred)
        if self.training:
            self.scored += 1
        return (self.weights * ((pred - true) / true) ** 2).sum(dim=1).mean()
