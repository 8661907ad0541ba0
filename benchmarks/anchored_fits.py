"""The anchored estimator's fits of a training batch, solved once against solved twice.

    python benchmarks/anchored_fits.py [--batches 30] [overrides...]

experiment=anchored's model (the likelihood anchor and the MAP fit of model.net.prior) on batches of its training
windows (data.seat_spread=0.3, batch 64, each window's noise std log-uniform in [0.003, 0.1]), one thread. "once":
``AnchoredCNN.fits``, whose MAP fit starts from the ML fit it returns as the anchor; "twice": the anchor's own ML
fit and the MAP fit's, as the model computed them before. The two are timed in turn on the same batch so that
the machine's drift cancels; the ratio of the medians, and whether the numbers are the same to the bit.
"""

import argparse
import time

import numpy as np
import torch
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.training.build import build_datamodule, build_model


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--batches", type=int, default=30)
    args, overrides = ap.parse_known_args()
    torch.set_num_threads(1)
    with initialize_config_dir(config_dir=CONF_DIR, version_base=None):
        cfg = compose("config", overrides=["experiment=anchored_clean", "estimator=anchored_cross_segment", *overrides])
    dm = build_datamodule(cfg)
    dm.setup("fit")
    model = build_model(cfg).net
    batches = iter(dm.train_dataloader())
    once, twice, same = [], [], True
    for i in range(args.batches):
        signals = next(batches)["signals"]
        x = signals.double().numpy()

        def solved_once(signals=signals):
            return model.fits(signals)

        def solved_twice(signals=signals, x=x):
            anchor = model.anchor(signals)
            return anchor, model.map.fit_windows(x[:, 0], x[:, 1], model.dt, model.measurement)

        # in turn, the first of each pair alternating: the second call of a batch finds the first's caches warm
        order = [(solved_once, once), (solved_twice, twice)][:: 1 if i % 2 == 0 else -1]
        out = {}
        for fn, times in order:
            t0 = time.perf_counter()
            out[fn] = fn()
            times.append(time.perf_counter() - t0)
        (fit, map_fit), (anchor, separate) = out[solved_once], out[solved_twice]
        pairs = zip((*fit[:2], *map_fit), (*anchor[:2], *separate))
        same &= all(np.array_equal(a, b, equal_nan=True) for a, b in pairs)
    print(f"{args.batches} training batches of {signals.shape[0]} windows, {signals.shape[-1]} samples")
    print(f"  solved once  median {np.median(once):.3f} s a batch")
    print(f"  solved twice median {np.median(twice):.3f} s a batch")
    print(f"  once / twice: {np.median(once) / np.median(twice):.3f}; the same numbers to the bit: {same}")


if __name__ == "__main__":
    main()
