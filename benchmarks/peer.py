"""The main job as the plain PyTorch script a user would write instead of using the framework, and a benchmark of
the two.

The peer does the main job's work (``hybrid-sysid experiment=robustness``): objectives labelled, hybrid and
combined x seeds 0-2, fast_cnn, 1300 steps of batch 64 (AdamW, one-cycle schedule), validation every 100 steps
keeping the best weights by the figure the project's model selection uses (val/rel_dev; val/loss for the
label-free hybrid objective), then the test split scored at every noise level of the ladder with K = 1 and 8.
It uses the project's data (the same cached dataset, windows and noise: QuarterCarDataModule's plain torch
DataLoaders), network and objectives (plain nn.Modules), and nothing else of it: no Lightning, no Hydra, no
run directories, records, checkpoints, figures or summary; three processes of one torch thread each run the nine
jobs, as the main job's launcher does.

    python benchmarks/peer.py peer                # the peer alone: its table and time
    python benchmarks/peer.py compare [--rounds 2]  # both, alternating, and their ratio (benchmarks/README.md)

compare runs the two in the order project, peer, peer, project, ... (--rounds pairs), so a drift of the machine's
speed over the minutes they take touches both alike; the ratio is that of their summed times. The peer's jobs
also report where their time went: start (imports, data), fit (training with its validations) and evaluation.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from machine import cpu_name, load_average

OBJECTIVES, SEEDS = ("labelled", "hybrid", "combined"), (0, 1, 2)
STEPS, EVAL_EVERY, BATCH, LR, WEIGHT_DECAY, WARMUP = 1300, 100, 64, 2e-2, 1e-2, 0.3
NOISE, WINDOWS = (0.0, 0.003, 0.01, 0.03, 0.1), (1, 8)
CACHE = "outputs/.cache"


def job(args: tuple[str, int]) -> tuple[list[dict], dict]:
    """One objective and seed: train, select, score. Rows of the mean relative deviation per noise, K, parameter,
    and the seconds of its phases."""
    started = time.perf_counter()
    import torch

    from hybrid_sysid.data.datamodule import QuarterCarDataModule
    from hybrid_sysid.data.spec import DatasetSpec
    from hybrid_sysid.model.networks import FastCNN
    from hybrid_sysid.model.objectives import CombinedObjective, HybridObjective, LabelledObjective

    objective_name, seed = args
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    np.random.seed(seed)
    torch.use_deterministic_algorithms(True)
    torch.utils.deterministic.fill_uninitialized_memory = False  # as the project's runs: the same computation
    spec = DatasetSpec()  # data=default
    # the network's bounds and the label scale: p = (C3, K3) / m3 over the seat masses (${p_prior:...})
    p_min, p_max = spec.car.parameters(spec.m3_max), spec.car.parameters(spec.m3_min)
    p_scale = [(a + b) / 2 for a, b in zip(p_min, p_max)]
    objective = {
        "labelled": lambda: LabelledObjective(p_scale),
        "hybrid": lambda: HybridObjective(),
        "combined": lambda: CombinedObjective(p_scale),
    }[objective_name]()
    dm = QuarterCarDataModule(spec, cache_dir=CACHE, batch_size=BATCH, seed=seed)
    dm.setup("fit")
    net = FastCNN(p_min, p_max)
    opt = torch.optim.AdamW(net.parameters(), lr=LR, weight_decay=WEIGHT_DECAY)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=LR, total_steps=STEPS, pct_start=WARMUP)

    def validate() -> float:
        net.eval()
        with torch.no_grad():
            batch = dm.eval_batch("val", 0.0)
            pred = net(batch["signals"])
            if objective_name == "hybrid":  # label-free model selection, as the project's
                value = objective(pred, batch).item()
            else:
                value = ((pred - batch["params"]).abs() / batch["params"]).mean().item()
        net.train()
        return value

    best, best_state = math.inf, None
    fit_start = time.perf_counter()
    for step, batch in enumerate(dm.train_dataloader(), start=1):
        loss = objective(net(batch["signals"]), batch)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        if step % EVAL_EVERY == 0 or step == STEPS:
            value = validate()
            if value < best:
                best, best_state = value, {k: v.clone() for k, v in net.state_dict().items()}
        if step == STEPS:
            break
    fit_end = time.perf_counter()
    net.load_state_dict(best_state)
    net.eval()
    rows = []
    with torch.no_grad():
        for std in NOISE:
            for k in WINDOWS:
                batch = dm.eval_batch("test", std, windows=k)
                pred = net(batch["signals"]).double().numpy().reshape(-1, k, 2).mean(axis=1)
                true = batch["params"].double().numpy().reshape(-1, k, 2)[:, 0]
                dev = np.abs(pred - true) / true
                for i, name in enumerate(("p1", "p2")):
                    rows.append(
                        {"objective": objective_name, "seed": seed, "noise_std": std, "windows": k,
                         "parameter": name, "mean_rel_dev": float(dev[:, i].mean())}
                    )  # fmt: skip
    phases = {"start": fit_start - started, "fit": fit_end - fit_start, "evaluation": time.perf_counter() - fit_end}
    return rows, phases


def peer() -> tuple[pd.DataFrame, float, pd.DataFrame]:
    """The nine jobs, three at a time (spawned processes, as joblib's loky workers). Returns the rows, the wall
    time and each job's phases."""
    start = time.perf_counter()
    with mp.get_context("spawn").Pool(3) as pool:
        done = pool.map(job, [(o, s) for o in OBJECTIVES for s in SEEDS], chunksize=1)
    rows = [row for job_rows, _ in done for row in job_rows]
    return pd.DataFrame(rows), time.perf_counter() - start, pd.DataFrame([phases for _, phases in done])


def table(rows: pd.DataFrame) -> pd.DataFrame:
    """Mean and std over seeds, in percent: objective x K rows, noise x parameter columns."""
    g = rows.groupby(["objective", "windows", "noise_std", "parameter"]).mean_rel_dev
    out = (100 * g.mean()).round(2).astype(str) + " ± " + (100 * g.std(ddof=1)).round(2).astype(str)
    return out.unstack(["noise_std", "parameter"])


def project(sweep_dir: Path) -> tuple[pd.DataFrame, float]:
    """``hybrid-sysid experiment=robustness`` into sweep_dir; its test rows and the wall time (fit_seconds in
    each job's record: training with its validations and learning-curve points)."""
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "hybrid_sysid", "experiment=robustness", f"hydra.sweep.dir={sweep_dir}"],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    seconds = time.perf_counter() - start
    runs = pd.read_csv(sweep_dir / "summary.csv")
    test = runs[(runs.split == "test") & (runs.status == "completed")]
    fit = [json.loads(f.read_text())["fit_seconds"] for f in sorted(sweep_dir.glob("*/metrics.json"))]
    print(f"  project jobs' fit (median of {len(fit)}): {np.median(fit):.1f} s", flush=True)
    return test[["objective", "seed", "noise_std", "windows", "parameter", "mean_rel_dev"]], seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("what", choices=("peer", "compare"))
    parser.add_argument("--rounds", type=int, default=2, help="compare: pairs of runs, in the order ABBA...")
    args = parser.parse_args()
    from hybrid_sysid.data.cache import get_dataset
    from hybrid_sysid.data.spec import DatasetSpec

    get_dataset(DatasetSpec(), CACHE)  # both sides start from the cached dataset
    print(f"CPU: {cpu_name()}, {mp.cpu_count()} cores, load average {load_average()}", flush=True)
    order = (
        ["peer"]
        if args.what == "peer"
        else [s for i in range(args.rounds) for s in ("project", "peer")[:: 1 - 2 * (i % 2)]]
    )
    times = {"project": [], "peer": []}
    for side in order:
        if side == "project":
            with tempfile.TemporaryDirectory() as tmp:
                summary, seconds = project(Path(tmp) / "robustness")
        else:
            rows, seconds, phases = peer()
            print(
                "  peer jobs' phases (median of 9): " + ", ".join(f"{k} {v:.1f} s" for k, v in phases.median().items())
            )
        times[side].append(seconds)
        print(f"{side}: {seconds:.1f} s (load average after: {load_average()})", flush=True)
    print("\npeer, test split, mean relative deviation [%], mean ± std over seeds:\n" + table(rows).to_markdown())
    if args.what == "compare":
        print("\nproject, the same:\n" + table(summary).to_markdown())
        # the same computation: each cell's gap between the two, against the two seed spreads added
        g = ["objective", "windows", "noise_std", "parameter"]
        a, b = (x.groupby(g).mean_rel_dev for x in (rows, summary))
        gap = (a.mean() - b.mean()).abs() / (a.std(ddof=1) + b.std(ddof=1))
        same = int(((100 * a.mean()).round(2) == (100 * b.mean()).round(2)).sum())
        print(f"\ncells equal to the digit: {same} of {len(gap)}; gap beyond the two seed spreads added: "
              f"{int((gap > 1).sum())}")  # fmt: skip
        pairs = [f"{p / q:.2f}" for p, q in zip(times["project"], times["peer"])]
        print(f"project {sum(times['project']):.1f} s, peer {sum(times['peer']):.1f} s in all; ratio project / peer "
              f"{sum(times['project']) / sum(times['peer']):.2f} (per pair: {', '.join(pairs)})")  # fmt: skip


if __name__ == "__main__":
    main()
