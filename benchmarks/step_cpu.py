"""How close a fast_cnn training step comes to the CPU: its FLOP count, the fraction of one thread's float32 matmul
rate it reaches, and what layout and fusion changes buy, each timed against the plain step in the same run.

    python benchmarks/step_cpu.py [--rounds 60] [--batch 64] [--no-compile]

One torch thread (as each job of the main job runs), deterministic algorithms on (as the Trainer runs), batch 64 of
500-step windows, the labelled objective, AdamW. The variants run round-robin, one step each per round, so a drift
of the machine's speed touches them alike; reported: the median step time of each and its ratio to the plain step.

- plain: the project's FastCNN as a run trains it;
- channels_last_2d: each Conv1d run as a Conv2d over a (C, 1, L) image in channels-last memory format, the layout
  oneDNN prefers for 2D convolutions (1D convolutions have no channels-last format of their own);
- fused_bn_relu: BatchNorm and ReLU in one elementwise pass after the convolution (the batch statistics still
  need a pass of their own);
- compiled: ``torch.compile`` of the network (inductor fuses normalisation, activation and the pointwise head);
  its first step, which compiles, is reported apart, and again in two fresh processes sharing a new inductor
  cache directory: the first compiles from nothing (a fresh machine, the main job's first round), the second finds
  the compiled graphs on disk. With the step times this gives what compiling would save or cost the main job
  (9 jobs of 1300 steps on 2 cores, 3 worker processes that each compile once).

The FLOP count is torch.utils.flop_counter's (convolutions and matrix products, forward and backward) for one step;
the matmul rate is the median of timed (512 x 512) @ (512 x 512) float32 products on one thread.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import torch
from machine import cpu_name, load_average
from torch import nn
from torch.utils.flop_counter import FlopCounterMode

from hybrid_sysid.model.networks import FastCNN
from hybrid_sysid.model.objectives import LabelledObjective

P_MIN, P_MAX = [615.0 / 200, 98935.0 / 200], [615.0 / 50, 98935.0 / 50]  # data=default's prior (${p_prior:...})
P_SCALE = [(a + b) / 2 for a, b in zip(P_MIN, P_MAX)]


class Conv2dAs1d(nn.Module):
    """A Conv1d's weights run as a Conv2d over (N, C, 1, L) in channels-last memory format."""

    def __init__(self, conv: nn.Conv1d):
        super().__init__()
        self.conv = nn.Conv2d(
            conv.in_channels,
            conv.out_channels,
            (1, conv.kernel_size[0]),
            stride=(1, conv.stride[0]),
            padding=(0, conv.padding[0]),
            bias=conv.bias is not None,
        )
        with torch.no_grad():
            self.conv.weight.copy_(conv.weight.unsqueeze(2))
            if conv.bias is not None:
                self.conv.bias.copy_(conv.bias)
        self.conv = self.conv.to(memory_format=torch.channels_last)

    def forward(self, x):
        y = self.conv(x.unsqueeze(2).contiguous(memory_format=torch.channels_last))
        return y.squeeze(2)


class BnRelu(nn.Module):
    """Training-mode BatchNorm1d followed by ReLU, the normalisation and activation in one expression."""

    def __init__(self, bn: nn.BatchNorm1d):
        super().__init__()
        self.bn = bn

    def forward(self, x):
        mean = x.mean(dim=(0, 2), keepdim=True)
        var = x.var(dim=(0, 2), unbiased=False, keepdim=True)
        scale = self.bn.weight[None, :, None] * torch.rsqrt(var + self.bn.eps)
        return torch.relu((x - mean) * scale + self.bn.bias[None, :, None])


def network(variant: str) -> nn.Module:
    torch.manual_seed(0)
    net = FastCNN(P_MIN, P_MAX)
    layers = list(net.features)
    if variant == "channels_last_2d":
        net.features = nn.Sequential(*[Conv2dAs1d(m) if isinstance(m, nn.Conv1d) else m for m in layers])
    elif variant == "fused_bn_relu":
        out, i = [], 0
        while i < len(layers):
            if isinstance(layers[i], nn.BatchNorm1d) and i + 1 < len(layers) and isinstance(layers[i + 1], nn.ReLU):
                out.append(BnRelu(layers[i]))
                i += 2
            else:
                out.append(layers[i])
                i += 1
        net.features = nn.Sequential(*out)
    return net


def batch(size: int) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    p = torch.tensor(P_MIN) + torch.rand(size, 2, generator=g) * (torch.tensor(P_MAX) - torch.tensor(P_MIN))
    return {"signals": torch.randn(size, 2, 500, generator=g), "params": p}


class Stepper:
    def __init__(self, variant: str, size: int):
        self.net = network(variant)
        self.forward = torch.compile(self.net) if variant == "compiled" else self.net
        self.opt = torch.optim.AdamW(self.net.parameters(), lr=2e-3, weight_decay=1e-2)
        self.objective = LabelledObjective(P_SCALE)
        self.batch = batch(size)

    def __call__(self) -> float:
        t = time.perf_counter()
        self.opt.zero_grad(set_to_none=True)
        self.objective(self.forward(self.batch["signals"]), self.batch).backward()
        self.opt.step()
        return time.perf_counter() - t


def step_flops(size: int) -> int:
    step = Stepper("plain", size)
    with FlopCounterMode(display=False) as counter:
        step()
    return counter.get_total_flops()


def matmul_rate(n: int = 512, repeats: int = 50) -> float:
    a, b = torch.randn(n, n), torch.randn(n, n)
    for _ in range(5):
        a @ b
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        a @ b
        times.append(time.perf_counter() - t)
    return 2 * n**3 / float(np.median(times))


def first_compiled_steps(size: int) -> tuple[float, float]:
    """The compiling first step of a fresh process, with an empty inductor cache and then with the one it left."""
    times = []
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "TORCHINDUCTOR_CACHE_DIR": cache}
        for _ in range(2):
            out = subprocess.run(
                [sys.executable, __file__, "--first-step", "--batch", str(size)],
                env=env,
                check=True,
                capture_output=True,
                text=True,
            ).stdout
            times.append(float(out.split()[-1]))
    return times[0], times[1]


def settings() -> None:
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True)
    torch.utils.deterministic.fill_uninitialized_memory = False  # as the runs (training/build.py)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=60)
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--no-compile", action="store_true", help="leave out torch.compile")
    parser.add_argument("--first-step", action="store_true", help=argparse.SUPPRESS)  # first_compiled_steps
    args = parser.parse_args()
    settings()
    if args.first_step:
        print(Stepper("compiled", args.batch)())
        return
    names = ["plain", "channels_last_2d", "fused_bn_relu"] + ([] if args.no_compile else ["compiled"])
    steppers = {}
    for name in names:
        steppers[name] = Stepper(name, args.batch)
        first = steppers[name]()
        if name == "compiled":
            print(f"compiled: first step (compiling) {first:.1f} s")
    for _ in range(5):
        for step in steppers.values():
            step()
    times = {name: [] for name in names}
    for _ in range(args.rounds):
        for name, step in steppers.items():
            times[name].append(step())
    flops, rate = step_flops(args.batch), matmul_rate()
    plain = float(np.median(times["plain"]))
    print(f"{cpu_name()}, 1 thread, batch {args.batch}, {args.rounds} rounds, load average {load_average()}")
    print(f"a step: {flops / 1e9:.3f} GFLOP (convolutions and matmuls, forward and backward)")
    print(f"float32 matmul (512^3) on one thread: {rate / 1e9:.1f} GFLOP/s")
    print("| variant | step [ms] | against plain | FLOP rate | of the matmul rate |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name in names:
        t = float(np.median(times[name]))
        print(f"| {name} | {1000 * t:.2f} | {t / plain:.3f} | {flops / t / 1e9:.1f} GFLOP/s | {flops / t / rate:.0%} |")
    if "compiled" in names:
        cold, warm = first_compiled_steps(args.batch)
        saved = (plain - float(np.median(times["compiled"]))) * 1300 * 9 / 2  # steps of the main job, 2 cores
        print(
            f"compiling in a fresh process: {cold:.1f} s with an empty cache, "
            f"{warm:.1f} s with the compiled graphs on disk"
        )
        print(
            f"the main job: steps {saved:.0f} s shorter on two cores; compiling in its 3 workers costs "
            f"{3 * cold / 2:.0f} s on a fresh machine, {3 * warm / 2:.0f} s once cached"
        )


if __name__ == "__main__":
    main()
