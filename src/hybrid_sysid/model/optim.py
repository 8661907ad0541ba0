"""The optimiser's settings (model.optim), checked here once; plain Python, so the config's checks run them in a
process that has not loaded torch. IdentificationModule builds its optimiser and schedule from them."""

from __future__ import annotations

from dataclasses import dataclass

from hybrid_sysid.core.checks import bad, check_choice, check_number
from hybrid_sysid.core.options import OPTIMIZERS, SCHEDULES

LR_MAX = 10.0  # a learning rate above it gives a NaN loss within a few steps (the defaults are 3e-3 to 5e-3)


@dataclass(frozen=True)
class OptimSettings:
    name: str = "adamw"  # core.options.OPTIMIZERS
    lr: float = 3e-3  # the peak rate of the one-cycle schedule
    weight_decay: float = 0.0
    schedule: str = "onecycle"  # constant, or one-cycle: warm up for warmup_fraction of the steps, then anneal
    warmup_fraction: float = 0.3

    def validate(self) -> None:
        check_choice("name", self.name, OPTIMIZERS)
        check_choice("schedule", self.schedule, SCHEDULES)
        # Adam's step moves each weight by about lr: beyond LR_MAX the first steps overflow float32 into a NaN loss
        check_number("lr", self.lr, 0, low_open=True)
        check_number("lr", self.lr, high=LR_MAX)
        check_number("weight_decay", self.weight_decay, 0)
        if self.lr * self.weight_decay >= 1:  # each step scales the weights by 1 - lr x weight_decay
            bad("weight_decay", self.weight_decay, f"below 1 / lr = {1 / self.lr:.4g} (each step shrinks the weights)")
        check_number("warmup_fraction", self.warmup_fraction, 0, 1, low_open=True, high_open=True)
