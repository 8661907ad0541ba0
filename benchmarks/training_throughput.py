"""Training throughput: the same model, batches and steps through a plain PyTorch loop and through the
project's Trainer path (ParameterEstimator + QCMDataModule + lightning.Trainer), timed in one script.

    python benchmarks/training_throughput.py [--steps 300] [overrides...]

Both paths draw the same training batches from the same data module; validation is off in both, so the ratio
measures what the framework adds to a step. The two paths alternate for --rounds rounds (the first round warms
caches and the CPU) and the median rate of each is compared: single timings on this machine vary by +-15%.
Reports steps per second and the ratio project / plain.
"""

import argparse
import time

import lightning as L
import numpy as np
import torch
from hydra import compose, initialize_config_dir

from hybrid_sysid.train import CONF_DIR, build_datamodule, build_model


def plain_loop(cfg, dm, steps):
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
    t0 = time.perf_counter()
    for _ in range(steps):
        batch = next(it)
        loss = model.objective(model(batch["signals"]), batch)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if sched is not None:
            sched.step()
    return steps / (time.perf_counter() - t0)


class StepTimer(L.Callback):
    def __init__(self, warmup=5):
        self.warmup, self.t0, self.n = warmup, None, 0

    def on_train_batch_start(self, trainer, *args):
        if trainer.global_step == self.warmup and self.t0 is None:
            self.t0 = time.perf_counter()

    def on_train_end(self, trainer, *args):
        self.rate = (trainer.global_step - self.warmup) / (time.perf_counter() - self.t0)


def trainer_path(cfg, dm, steps):
    L.seed_everything(cfg.seed)
    model = build_model(cfg)
    timer = StepTimer()
    trainer = L.Trainer(max_steps=steps + timer.warmup, limit_val_batches=0, logger=False, enable_checkpointing=False,
                        enable_progress_bar=bool(cfg.trainer.progress_bar), enable_model_summary=False,
                        deterministic=cfg.trainer.deterministic, accelerator="cpu", devices=1, callbacks=[timer])
    trainer.fit(model, datamodule=dm)
    return timer.rate


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=["trainer.progress_bar=true", *args.overrides])
    dm = build_datamodule(cfg)
    dm.setup("fit")
    print(f"torch threads: {torch.get_num_threads()}; model {cfg.model.net._target_}, batch {cfg.model.batch_size}, "
          f"window {cfg.data.window}, {args.steps} timed steps")
    rates = {"plain loop": [], "project Trainer path": []}
    for r in range(args.rounds):
        order = [("plain loop", plain_loop), ("project Trainer path", trainer_path)]
        for name, fn in (order if r % 2 == 0 else order[::-1]):
            rates[name].append(fn(cfg, dm, args.steps))
            print(f"round {r}: {name}: {rates[name][-1]:.2f} steps/s")
    med = {name: float(np.median(v[1:] if len(v) > 1 else v)) for name, v in rates.items()}
    for name, v in med.items():
        print(f"{name}: median {v:.2f} steps/s (rounds after the first)")
    print(f"ratio project / plain: {med['project Trainer path'] / med['plain loop']:.3f}")


if __name__ == "__main__":
    main()
