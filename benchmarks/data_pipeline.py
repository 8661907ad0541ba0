"""Training batches: the project's window cropping against two references, timed in one run.

    python benchmarks/data_pipeline.py [--batches 300] [overrides...]

On the default data (the run's config), each way cuts the same (recording, start) pairs of batch 64 x window
500 from the four float32 channels (seat, body, relative velocity and displacement) and must give identical
tensors:
- a per-sample Python loop (arr[row, start:start + window] for each sample, stacked): the obvious way;
- torch advanced indexing with a (batch, window) column index, the other vectorised way;
- the project: one numpy index into a sliding-window view per channel (hybrid_sysid.data.datamodule).
Then the whole training batch as Lightning receives it (next() on the data module's train loader: window
draw, cropping, the dict), against the median step of a default training run from the benchmarks README.
Memory: the window views share the dataset's buffers (no copy), and the loader runs in the main process
(no workers, so no per-worker copy).
"""

import argparse
import time

import numpy as np
import torch
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.data.windows import gather
from hybrid_sysid.training.build import build_datamodule


def per_sample_loop(arrays, rows, starts, window):
    return [
        torch.stack([torch.from_numpy(a[r, s : s + window]) for r, s in zip(rows.tolist(), starts.tolist())])
        for a in arrays
    ]


def torch_advanced_index(tensors, rows, starts, window):
    rows, starts = torch.from_numpy(rows), torch.from_numpy(starts)
    cols = starts[:, None] + torch.arange(window)
    return [t[rows[:, None], cols] for t in tensors]


def project(views, rows, starts, window):
    return [gather(v, rows, starts) for v in views]


def median_us(fn, n):
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) * 1e6


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--batches", type=int, default=300)
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=args.overrides)
    dm = build_datamodule(cfg)
    dm.setup("fit")
    ds, data = dm.dataset, dm.train_windows.data
    window, batch = cfg.data.window, cfg.model.batch_size
    arrays = [ds.seat_acc, ds.body_acc, ds.rel_vel, ds.rel_disp]
    tensors = [torch.from_numpy(a) for a in arrays]
    views = [data.seat, data.body, data.rel_vel, data.rel_disp]
    rng = np.random.default_rng(0)
    rows = rng.choice(dm.rows("train"), size=batch)
    starts = rng.integers(0, ds.seat_acc.shape[1] - window + 1, size=batch)

    ways = {
        "per-sample Python loop": lambda: per_sample_loop(arrays, rows, starts, window),
        "torch advanced indexing": lambda: torch_advanced_index(tensors, rows, starts, window),
        "project: window views": lambda: project(views, rows, starts, window),
    }
    want = ways["per-sample Python loop"]()
    for name, fn in ways.items():
        assert all(torch.equal(g, w) for g, w in zip(fn(), want)), f"{name} cuts different windows"
    print(
        f"dataset {ds.seat_acc.shape[0]} recordings x {ds.seat_acc.shape[1]} steps; batch {batch}, window {window}, "
        f"4 channels; median of {args.batches} batches, torch threads {torch.get_num_threads()}"
    )
    print("| cropping one batch (4 channels) | median | vs per-sample loop |")
    print("| --- | ---: | ---: |")
    loop_us = None
    for name, fn in ways.items():
        us = median_us(fn, args.batches)
        loop_us = loop_us or us
        print(f"| {name} | {us:.0f} us | {loop_us / us:.1f}x |")

    it = iter(dm.train_dataloader())
    next(it)
    us = median_us(lambda: next(it), args.batches)
    print(f"whole training batch from the loader (draw, crop, dict): {us:.0f} us")
    shared = all(np.shares_memory(v, a) for v, a in zip(views, arrays))
    print(
        f"window views share the dataset's memory: {shared}; train loader workers: {dm.train_dataloader().num_workers}"
    )


if __name__ == "__main__":
    main()
