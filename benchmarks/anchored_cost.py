"""The anchored estimator's cost against fast_cnn's: a training step, and the evaluation of the test split.

    python benchmarks/anchored_cost.py [--steps 200] [--train-std 0.01] [--rounds 5] [overrides...]

data=default with data.seat_spread=0.3, batch 64, window 500, one torch thread. Training: plain loops (batch
drawn by the data module, forward, loss, backward, AdamW step) of model=fast_cnn and model=anchored with the
labelled objective, interleaved step by step so the machine's drift cancels; the median of the per-step ratios.
The anchored step adds the window's band-passed least-squares fit (an FFT convolution of three signals and a
2 x 2 solve per window) and a small head. Evaluation: ``predict_split`` of the test split at noise 0.01, K = 1
and K = 8, the two models alternating for ``--rounds`` rounds; the ratio of the medians.
"""

import argparse
import time

import numpy as np
import torch
from filtered_objective_step import (  # the same plain training loop, from the script beside this one
    interleaved,
    stepper,
)

MODELS = ("fast_cnn", "anchored")


def parts(model_name, train_std, overrides):
    step = stepper("labelled", train_std, [f"model={model_name}", "data.seat_spread=0.3", *overrides])

    def evaluate(k):
        step.model.eval()
        with torch.no_grad():
            step.model.predict_split(step.dm, "test", 0.01, windows=k)
        step.model.train()

    return step, evaluate


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--train-std", type=float, default=0.01)
    ap.add_argument("--rounds", type=int, default=5)
    args, overrides = ap.parse_known_args()
    torch.set_num_threads(1)
    built = {m: parts(m, args.train_std, overrides) for m in MODELS}
    times = interleaved({m: built[m][0] for m in MODELS}, args.steps)
    ratio = np.array(times["anchored"]) / np.array(times["fast_cnn"])
    print(f"{args.steps} interleaved training steps, noise.train_std={args.train_std} {' '.join(overrides)}")
    for m in MODELS:
        print(f"  {m:9s} median step {1000 * np.median(times[m]):6.2f} ms")
    print(
        f"  anchored / fast_cnn per step: median {np.median(ratio):.3f} "
        f"(interquartile {np.quantile(ratio, 0.25):.3f}-{np.quantile(ratio, 0.75):.3f}; goal <= 1.2)"
    )
    for k in (1, 8):
        ev = {m: [] for m in MODELS}
        for m in MODELS:
            built[m][1](k)  # warm-up: the data module caches its evaluation windows
        for _ in range(args.rounds):
            for m in MODELS:
                t0 = time.perf_counter()
                built[m][1](k)
                ev[m].append(time.perf_counter() - t0)
        med = {m: float(np.median(ev[m])) for m in MODELS}
        print(
            f"test split at noise 0.01, K = {k}: fast_cnn {med['fast_cnn']:.3f} s, anchored {med['anchored']:.3f} s, "
            f"ratio {med['anchored'] / med['fast_cnn']:.3f} (goal <= 1.5)"
        )


if __name__ == "__main__":
    main()
