"""What the anchored estimator's fits of a training batch cost under each recording fault, against the clean fit.

    python benchmarks/fault_fit_cost.py [--batches 8] [--faults clean gain skewed lowpass hardening] [overrides...]

experiment=anchored's model (the likelihood anchor with the fault's fix, and the MAP fit of model.net.prior) on
batches of its training windows (data.seat_spread=0.3, batch 64, each window's noise std log-uniform in
[0.003, 0.1]), one thread. Per fault: the median CPU seconds of ``AnchoredCNN.fits`` over the batches, and its
ratio to the clean fit's. A network under a fault pays this on every training step, so it sets how long
``experiment=anchored``'s fault rows train. To compare two versions of the code, run it once with each on
``PYTHONPATH`` in turn; the faults' windows are the same for the same overrides.
"""

import argparse
import time

import numpy as np
import torch
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.training.build import build_datamodule, build_model


def per_batch(fault: str, n: int, overrides) -> float:
    with initialize_config_dir(config_dir=CONF_DIR, version_base=None):
        cfg = compose(
            "config",
            overrides=["experiment=anchored", "estimator=anchored_label_free", f"fault={fault}", *overrides],
        )
    torch.manual_seed(0)
    dm = build_datamodule(cfg)
    dm.setup("fit")
    model = build_model(cfg).net
    batches = iter(dm.train_dataloader())
    times = []
    for _ in range(n):
        signals = next(batches)["signals"]
        t0 = time.process_time()
        model.fits(signals)
        times.append(time.process_time() - t0)
    return float(np.median(times))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--batches", type=int, default=8)
    ap.add_argument("--faults", nargs="+", default=["clean", "gain", "skewed", "lowpass", "hardening"])
    args, overrides = ap.parse_known_args()
    torch.set_num_threads(1)
    cost = {fault: per_batch(fault, args.batches, overrides) for fault in args.faults}
    print(f"the anchored estimator's fits of a training batch of 64 windows, median of {args.batches} batches")
    for fault, seconds in cost.items():
        ratio = f"  {seconds / cost['clean']:5.1f}x clean" if "clean" in cost else ""
        print(f"  {fault:10s} {seconds:6.3f} s of CPU{ratio}")


if __name__ == "__main__":
    main()
