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
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.training.build import build_datamodule, build_model

MODELS = ("fast_cnn", "anchored")


def parts(model_name, train_std, overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base=None):
        cfg = compose(
            "config",
            overrides=[f"model={model_name}", "data.seat_spread=0.3", f"noise.train_std={train_std}", *overrides],
        )
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

    def evaluate(k):
        model.eval()
        with torch.no_grad():
            model.predict_split(dm, "test", 0.01, windows=k)
        model.train()

    return step, evaluate


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--train-std", type=float, default=0.01)
    ap.add_argument("--rounds", type=int, default=5)
    args, overrides = ap.parse_known_args()
    torch.set_num_threads(1)
    built = {m: parts(m, args.train_std, overrides) for m in MODELS}
    times = {m: [] for m in MODELS}
    for i in range(args.steps + 10):
        for m in MODELS:
            t0 = time.perf_counter()
            built[m][0]()
            if i >= 10:  # warm-up
                times[m].append(time.perf_counter() - t0)
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
