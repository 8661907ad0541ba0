"""Training throughput: the same model, batches and steps through a plain PyTorch loop and through the
project's Trainer path (IdentificationModule with Lightning's automatic optimisation + QuarterCarDataModule + the run's
lightning.Trainer and training clock), timed in one script.

    python benchmarks/training_throughput.py [--steps 600] [--tiny] [overrides...]               # interleaved
    python benchmarks/training_throughput.py --rounds 20 [--steps 60] [--tiny] [overrides...]    # rounds

Both paths draw the same training batches from the same data module; validation is off in both, so the ratio
measures what the framework adds to a step. This machine's speed drifts by +-15% within a minute, so the two
paths are timed close together:
- interleaved (default): one Trainer run of --steps steps; after each of its steps a callback runs one step of
  the plain loop (its own model, optimiser and batch iterator). A Trainer step is the time from one batch start
  to the next less the plain step run in between (Lightning's hooks, our callback's dispatch included), so
  each pair of steps is 20-50 ms apart. Reported: the ratio of median step times and the median of the
  per-pair ratios with its interquartile range.
- --rounds N: the two paths back to back in alternating order, N short rounds of --steps steps (after one
  warm-up round); each round gives a ratio of median step times, and the median of those ratios is reported.
With --tiny the network is a 2 -> 2 linear map of the window's mean: the step is then almost all framework and
data, so the difference between the paths is the Trainer path's fixed cost per step.
"""

import argparse
import tempfile
import time

import lightning as L
import numpy as np
import torch
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.model.module import IdentificationModule
from hybrid_sysid.training.build import build_datamodule, build_model, build_trainer
from hybrid_sysid.training.callbacks import TrainingClock


class TinyNet(torch.nn.Module):
    def __init__(self):
        super().__init__()
        self.linear = torch.nn.Linear(2, 2)

    def forward(self, signals):
        return self.linear(signals.mean(-1))


def tiny_model(cfg):
    return IdentificationModule(TinyNet(), instantiate(cfg.objective, _convert_="all"), max_steps=cfg.trainer.max_steps)


MAKE_MODEL = [build_model]  # or tiny_model with --tiny


def plain_loop(cfg, dm, steps):
    # the same algorithms as the Trainer path: with trainer.deterministic, Lightning turns on torch's
    # deterministic algorithms (about 5% slower on these cores); the plain loop gets them too
    torch.use_deterministic_algorithms(bool(cfg.trainer.deterministic))
    try:
        return _plain_loop(cfg, dm, steps)
    finally:
        torch.use_deterministic_algorithms(False)


def _plain_loop(cfg, dm, steps):
    step = plain_stepper(cfg, dm)
    for _ in range(5):  # warm-up, as the Trainer path gets
        step()
    stamps = [time.perf_counter()]
    for _ in range(steps):
        step()
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


class Interleaved(L.Callback):
    """After every Trainer step, one plain-loop step; both timed (see the module's docstring)."""

    def __init__(self, plain_step, warmup=5):
        self.plain_step, self.warmup = plain_step, warmup
        self.starts, self.plain = [], []

    def on_train_batch_start(self, trainer, *args):
        if trainer.global_step >= self.warmup:
            self.starts.append(time.perf_counter())

    def on_train_batch_end(self, trainer, *args):
        t0 = time.perf_counter()
        self.plain_step()
        if trainer.global_step > self.warmup:  # global_step has counted this step already
            self.plain.append(time.perf_counter() - t0)

    def on_train_end(self, trainer, *args):
        self.starts.append(time.perf_counter())


def plain_stepper(cfg, dm):
    """One plain-loop step per call: the same model, optimiser, schedule and batches as plain_loop."""
    L.seed_everything(cfg.seed)
    model = MAKE_MODEL[0](cfg)
    opt_cfg = model.configure_optimizers()
    if isinstance(opt_cfg, dict):
        opt, sched = opt_cfg["optimizer"], opt_cfg["lr_scheduler"]["scheduler"]
    else:
        opt, sched = opt_cfg, None
    model.train()
    it = iter(dm.train_dataloader())

    def step():
        batch = next(it)
        loss = model.objective(model(batch["signals"]), batch)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if sched is not None:
            sched.step()

    return step


def interleaved(cfg, dm, steps):
    """(plain step times, Trainer step times), pair by pair."""
    callback = Interleaved(plain_stepper(cfg, dm))
    L.seed_everything(cfg.seed)
    model = MAKE_MODEL[0](cfg)
    with tempfile.TemporaryDirectory() as tmp:
        trainer = build_trainer(
            cfg,
            tmp,
            [TrainingClock(), callback],
            max_steps=steps + callback.warmup,
            limit_val_batches=0,
            enable_checkpointing=False,
        )
        trainer.fit(model, datamodule=dm)
    plain = np.array(callback.plain)
    # from one batch start to the next, less the plain step our callback ran in between
    project = np.diff(callback.starts)[: len(plain)] - plain
    return plain, project


def trainer_path(cfg, dm, steps):
    L.seed_everything(cfg.seed)
    model = MAKE_MODEL[0](cfg)
    timer = StepTimer()
    with tempfile.TemporaryDirectory() as tmp:  # the run's own Trainer, minus validation and checkpoints
        trainer = build_trainer(
            cfg,
            tmp,
            [TrainingClock(), timer],
            max_steps=steps + timer.warmup,
            limit_val_batches=0,
            enable_checkpointing=False,
        )
        trainer.fit(model, datamodule=dm)
    return np.diff(timer.stamps)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument(
        "--steps",
        type=int,
        default=None,
        help="timed steps: per run (default 600 interleaved, 60 a round with --rounds)",
    )
    ap.add_argument("--rounds", type=int, default=0, help="time back-to-back rounds instead of interleaving")
    ap.add_argument("--tiny", action="store_true", help="a 2 -> 2 linear network: the framework's fixed cost")
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args()
    if args.tiny:
        MAKE_MODEL[0] = tiny_model
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=["trainer.progress_bar=true", *args.overrides])
    dm = build_datamodule(cfg)
    dm.setup("fit")
    net = "TinyNet (--tiny)" if args.tiny else cfg.model.net._target_
    if not args.rounds:
        args.steps = args.steps or 600
        print(
            f"torch threads: {torch.get_num_threads()}; model {net}, batch {cfg.model.batch_size}, "
            f"window {cfg.data.window}, {args.steps} interleaved pairs of steps"
        )
        plain_loop(cfg, dm, 20)  # warm-up of caches and the CPU
        torch.use_deterministic_algorithms(bool(cfg.trainer.deterministic))  # as the Trainer will
        plain, project = interleaved(cfg, dm, args.steps)
        torch.use_deterministic_algorithms(False)
        pm, jm = float(np.median(plain)), float(np.median(project))
        print(f"plain loop: median step {pm * 1e3:.2f} ms = {1 / pm:.2f} steps/s")
        print(f"project Trainer path: median step {jm * 1e3:.2f} ms = {1 / jm:.2f} steps/s")
        q1, q2, q3 = np.percentile(plain / project, [25, 50, 75])
        print(
            f"ratio project / plain (steps per second): {pm / jm:.3f} (ratio of medians); per pair: median "
            f"{q2:.3f} (interquartile {q1:.3f} to {q3:.3f}); difference of medians {(jm - pm) * 1e3:.2f} ms"
        )
        return
    args.steps = args.steps or 60
    print(
        f"torch threads: {torch.get_num_threads()}; model {net}, batch {cfg.model.batch_size}, "
        f"window {cfg.data.window}, {args.steps} timed steps x {args.rounds} rounds per path"
    )
    # This machine's speed drifts by up to +-15% within a minute, so pooled timings of long runs compare
    # whatever state each run happened to meet. Instead: many short runs, the two paths back to back in
    # alternating order, a ratio per round (median step of each), and the median of those ratios.
    names = ("plain loop", "project Trainer path")
    steps_s = {name: [] for name in names}
    ratios = []
    for r in range(-1, args.rounds):  # round -1 warms caches and the CPU and is dropped
        order = [(names[0], plain_loop), (names[1], trainer_path)]
        med = {}
        for name, fn in order if r % 2 == 0 else order[::-1]:
            dts = fn(cfg, dm, args.steps)
            med[name] = float(np.median(dts))
            if r >= 0:
                steps_s[name].append(dts)
        if r >= 0:
            ratios.append(med[names[0]] / med[names[1]])
            print(
                f"round {r}: plain {1 / med[names[0]]:.1f} steps/s, project {1 / med[names[1]]:.1f} steps/s, "
                f"ratio {ratios[-1]:.3f}",
                flush=True,
            )
    for name in names:
        v = float(np.median(np.concatenate(steps_s[name])))
        print(f"{name}: median step {v * 1e3:.2f} ms = {1 / v:.2f} steps/s (pooled over rounds)")
    q1, q2, q3 = np.percentile(ratios, [25, 50, 75])
    print(
        f"ratio project / plain (steps per second): median of {len(ratios)} paired rounds {q2:.3f} "
        f"(interquartile {q1:.3f} to {q3:.3f})"
    )


if __name__ == "__main__":
    main()
