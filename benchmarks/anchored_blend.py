"""The anchored estimator's blend weight (model.net.blend) on windows no run has seen.

    python benchmarks/anchored_blend.py RUN [RUN ...] [--data-seed 7] [--windows 1200] [--weights 0,0.25,0.5,0.75,1]

RUN: run directories of model=anchored (experiment=anchored's anchored rows, clean). Each run's network is loaded
from its best checkpoint and evaluated without the blend on windows of another dataset (the run's data config with
``data.seed`` = --data-seed, simulated or read from the cache); the Bayes estimate (baseline=eiv_bayes) is computed
on the same windows. Each weight g gives p^g p_bayes^(1 - g), the blend's formula; the table is the mean relative
deviation of p1 / p2 in % at each noise level, mean over the runs, with g = 0 the Bayes estimate alone and g = 1
the network alone. One thread; about two minutes a run.
"""

import argparse

import numpy as np
import torch
from omegaconf import OmegaConf

from hybrid_sysid.baselines.eiv_bayes import ErrorsInVariablesBayes
from hybrid_sysid.data.cache import get_dataset
from hybrid_sysid.data.spec import DatasetSpec
from hybrid_sysid.inference.loading import load_estimator
from hybrid_sysid.runs.rundir import RunDir

LEVELS = (0.003, 0.01, 0.03, 0.1)


def windows(cfg, data_seed: int, n: int, rng):
    """n windows (seat, body (n, W) each, float64) of distinct recordings of the dataset with seed ``data_seed``,
    at random starts, and their true p (n, 2)."""
    cfg = OmegaConf.merge(cfg, {"data": {"seed": data_seed}})
    spec = DatasetSpec.from_config(cfg)
    ds = get_dataset(spec, str(cfg.data.cache_dir))
    rows = rng.choice(ds.seat_acc.shape[0], n, replace=False)
    width = int(cfg.data.window)
    idx = rng.integers(0, ds.seat_acc.shape[1] - width + 1, n)[:, None] + np.arange(width)
    take = lambda a: np.take_along_axis(a[rows].astype(np.float64), idx, axis=1)  # noqa: E731
    return take(ds.seat_acc), take(ds.body_acc), ds.params[rows, :2].astype(np.float64), spec


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--data-seed", type=int, default=7)
    ap.add_argument("--windows", type=int, default=1200)
    ap.add_argument("--weights", default="0,0.25,0.5,0.75,1")
    args = ap.parse_args()
    torch.set_num_threads(1)
    weights = [float(g) for g in args.weights.split(",")]
    errors = {}  # (g, level) -> [per run (2,)]
    for run in args.runs:
        net = load_estimator(run).net.eval()
        net.bayes = None  # the network alone: the blend is computed below, at every weight
        cfg = RunDir(run).saved_config("run")
        rng = np.random.default_rng(123)  # the same windows and noise for every run
        seat0, body0, truth, spec = windows(cfg, args.data_seed, args.windows, rng)
        bayes = ErrorsInVariablesBayes(prior=dict(cfg.model.net.prior), dt=spec.dt)
        for std in LEVELS:
            seat = seat0 + std * rng.standard_normal(seat0.shape)
            body = body0 + std * rng.standard_normal(body0.shape)
            signals = torch.from_numpy(np.stack([seat, body], axis=1)).float()
            with torch.no_grad():
                p_net = net(signals).double().numpy()
            x = signals.double().numpy()  # what the network saw, float32
            p_bayes = bayes.fit_windows(x[:, 0], x[:, 1], spec.dt, spec.measurement)[0]
            p_bayes = np.where(np.isfinite(p_bayes) & (p_bayes > 0), p_bayes, p_net)  # the blend keeps p there
            for g in weights:
                p = p_net**g * p_bayes ** (1 - g)
                errors.setdefault((g, std), []).append(100 * np.abs(p / truth - 1).mean(axis=0))
        print(f"{run}: done", flush=True)
    print(f"\n{len(args.runs)} runs, {args.windows} windows of data.seed={args.data_seed}; p1 / p2 in %\n")
    print("| g | " + " | ".join(f"{s:g}" for s in LEVELS) + " |")
    print("| --- |" + " --- |" * len(LEVELS))
    for g in weights:
        cells = [np.mean(errors[(g, s)], axis=0) for s in LEVELS]
        name = {0.0: "0 (Bayes)", 1.0: "1 (network)"}.get(g, f"{g:g}")
        print(f"| {name} | " + " | ".join(f"{c[0]:.2f} / {c[1]:.2f}" for c in cells) + " |")


if __name__ == "__main__":
    main()
