"""Training throughput: the same model, batches and steps through a plain PyTorch loop and through the
project's Trainer path (ParameterEstimator + QCMDataModule + lightning.Trainer), timed in one script.

    python benchmarks/training_throughput.py [--steps 300] [overrides...]

Both paths draw the same training batches from the same data module; validation is off in both, so the ratio
measures what the framework adds to a step. The two paths alternate for --rounds rounds (the first round warms
caches and the CPU) and the median step time of each is compared: whole-run timings on this machine vary by
+-15%. Reports steps per second and the ratio project / plain.
"""

import argparse
import tempfile
import time

import lightning as L
import numpy as np
import torch
from hydra import compose, initialize_config_dir

from hybrid_sysid.train import CONF_DIR, build_datamodule, build_model, build_trainer


def plain_loop(cfg, dm, steps):
    # the same algorithms as the Trainer path: with trainer.deterministic, Lightning turns on torch's
    # deterministic algorithms (about 5% slower on these cores); the plain loop gets them too
    torch.use_deterministic_algorithms(bool(cfg.trainer.deterministic))
    try:
        return _plain_loop(cfg, dm, steps)
    finally:
        torch.use_deterministic_algorithms(False)


def _plain_loop(cfg, dm, steps):
    L.seed_everything(cfg.seed)
    model = build_model(cfg)
    opt_cfg = model.configure_optimizers()
    opt, sched = (opt_cfg["optimizer"], opt_cfg["lr_scheduler"]["scheduler"]) if isinstance(opt_cfg, dict) else (opt_cfg, None)
    model.train()
    it = iter(dm.train_dataloader())
    for _ in range(5):  # warm-up, as the Trainer path gets
        batch = next(it)
        loss = model.objective(model(batch["signals"]), batch)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
    stamps = [time.perf_counter()]
    for _ in range(steps):
        batch = next(it)
        loss = model.objective(model(batch["signals"]), batch)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if sched is not None:
            sched.step()
        stamps.append(time.perf_counter())
    return np.diff(stamps)


class StepTimer(L.Callback):
    """Time stamps at the start of every batch after the warm-up, and at the end of training."""

    def __init__(self, warmup=5):
        self.warmup, self.stamps = warmup, []

    def on_train_batch_start(self, trainer, *args):
        if trainer.global_step >= self.warmup:
            self.stamps.append(time.perf_counter())

    def on_train_end(self, trainer, *args):
        self.stamps.append(time.perf_counter())


def trainer_path(cfg, dm, steps):
    L.seed_everything(cfg.seed)
    model = build_model(cfg)
    timer = StepTimer()
    with tempfile.TemporaryDirectory() as tmp:  # the run's own Trainer, minus validation and checkpoints
        trainer = build_trainer(cfg, tmp, [timer], max_steps=steps + timer.warmup, limit_val_batches=0,
                                enable_checkpointing=False)
        trainer.fit(model, datamodule=dm)
    return np.diff(timer.stamps)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=["trainer.progress_bar=true", *args.overrides])
    dm = build_datamodule(cfg)
    dm.setup("fit")
    print(f"torch threads: {torch.get_num_threads()}; model {cfg.model.net._target_}, batch {cfg.model.batch_size}, "
          f"window {cfg.data.window}, {args.steps} timed steps")
    # Per-step times, pooled over rounds; the median step is robust to the bursts of interference that move
    # whole-run timings on this (virtual) machine by +-15%. The first round warms caches and is dropped.
    steps_s = {"plain loop": [], "project Trainer path": []}
    for r in range(args.rounds):
        order = [("plain loop", plain_loop), ("project Trainer path", trainer_path)]
        for name, fn in (order if r % 2 == 0 else order[::-1]):
            dts = fn(cfg, dm, args.steps)
            if r > 0:
                steps_s[name].append(dts)
            print(f"round {r}: {name}: {1 / np.median(dts):.2f} steps/s (median step), "
                  f"{len(dts) / dts.sum():.2f} steps/s (whole run)")
    med = {name: float(np.median(np.concatenate(v))) for name, v in steps_s.items()}
    for name, v in med.items():
        print(f"{name}: median step {v * 1e3:.2f} ms = {1 / v:.2f} steps/s")
    print(f"ratio project / plain (steps per second): {med['plain loop'] / med['project Trainer path']:.3f}")


if __name__ == "__main__":
    main()
