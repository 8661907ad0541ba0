"""The cost of a training step with the band-passed hybrid objective against today's unfiltered one.

    python benchmarks/filtered_objective_step.py [--steps 300] [--train-std 0.01] [overrides...]

fast_cnn, batch 64, window 500, data=default, one torch thread. Three plain training loops (batch drawn by the
data module, forward, loss, backward, AdamW step), interleaved step by step so the machine's drift cancels:
objective=hybrid, objective=hybrid_bandpass (the band-passed signals: the clean part gathered from arrays
filtered once per recording, the noise part through a torch conv1d per batch) and objective=hybrid_eiv.
Reported: the median step of each and the median of the per-step ratios to the unfiltered hybrid.
"""

import argparse
import time

import numpy as np
import torch
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.training.build import build_datamodule, build_model

OBJECTIVES = ("hybrid", "hybrid_bandpass", "hybrid_eiv")


def stepper(objective, train_std, overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base=None):
        cfg = compose("config", overrides=[f"objective={objective}", f"noise.train_std={train_std}", *overrides])
    torch.manual_seed(0)
    dm = build_datamodule(cfg)
    dm.setup("fit")
    model = build_model(cfg)
    opt = torch.optim.AdamW(model.parameters(), lr=1e-3)
    batches = iter(dm.train_dataloader())

    def step():
        batch = next(batches)
        loss = model.objective(model(batch["signals"]), batch)
        opt.zero_grad()
        loss.backward()
        opt.step()

    step.model, step.dm = model, dm  # for a caller that also evaluates (benchmarks/anchored_cost.py)
    return step


def interleaved(steps: dict, n: int, warm_up: int = 10) -> dict:
    """The seconds of each of ``n`` calls of every step, taken in turn so that the machine's drift cancels."""
    times = {name: [] for name in steps}
    for i in range(n + warm_up):
        for name, step in steps.items():
            t0 = time.perf_counter()
            step()
            if i >= warm_up:
                times[name].append(time.perf_counter() - t0)
    return times


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--train-std", type=float, default=0.01)
    args, overrides = ap.parse_known_args()
    torch.set_num_threads(1)
    times = interleaved({o: stepper(o, args.train_std, overrides) for o in OBJECTIVES}, args.steps)
    base = np.array(times["hybrid"])
    print(f"{args.steps} interleaved steps, noise.train_std={args.train_std}, {' '.join(overrides)}")
    for o in OBJECTIVES:
        t = np.array(times[o])
        r = t / base
        print(
            f"{o:16s} median step {1000 * np.median(t):6.2f} ms   per-step ratio to hybrid: median "
            f"{np.median(r):.3f} (interquartile {np.quantile(r, 0.25):.3f}-{np.quantile(r, 0.75):.3f})"
        )


if __name__ == "__main__":
    main()
