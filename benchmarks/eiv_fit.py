"""The classical estimators of one window against the Cramér-Rao bound, and their time: band-passed least squares
(estimator=ls), the errors-in-variables ML fit (estimator=eiv) and its MAP form with the simulator's prior
(estimator=eiv_map), on the test split of experiment=anchored's data.

    python benchmarks/eiv_fit.py [--seeds 0 1 2] [--noise 0 0.003 0.01 0.02 0.03 0.1] [--threads 1] [overrides...]

data=default with data.seat_spread=0.3, consistent recordings, K = 1: 400 test windows of 500 samples per noise
level, seeded per (seed, split) as every run's. For each estimator, the mean relative deviation (eq. 24) of p1 / p2
in percent, averaged over the seeds, and the median seconds of one noise level's fit of all 400 windows; beside
them the bound (model.metrics.bound_fields: sqrt(2 / pi) sigma times the mean Cramér-Rao relative standard
deviation) and each estimator's efficiency (1 for an efficient estimator). The estimators are the baselines' own
classes, called as a run calls them (``predict_split``); the bound is computed as a run's record computes it.
"""

import argparse
import time

import numpy as np
import torch
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.model.metrics import bound_fields, relative_deviation
from hybrid_sysid.training.build import build_baseline, build_datamodule
from hybrid_sysid.training.evaluation import recording_bounds

ESTIMATORS = ("ls", "eiv", "eiv_map")


def config(estimator, seed, overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(
            config_name="config",
            overrides=[f"estimator={estimator}", "data.seat_spread=0.3", f"seed={seed}", *overrides],
        )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.0, 0.003, 0.01, 0.02, 0.03, 0.1])
    ap.add_argument("--threads", type=int, default=1)
    args, overrides = ap.parse_known_args()
    torch.set_num_threads(args.threads)
    dev = {(e, s): [] for e in ESTIMATORS for s in args.noise}
    eff = {(e, s): [] for e in ESTIMATORS for s in args.noise}
    seconds = {e: [] for e in ESTIMATORS}
    bound = {s: [] for s in args.noise}
    for seed in args.seeds:
        dm = build_datamodule(config("ls", seed, overrides))
        dm.setup()
        both, output = recording_bounds(dm, "test", 1)
        for std in args.noise:
            dm.eval_batch("test", std)  # the windows and their noise drawn once, outside the timing
            rows = bound_fields(np.zeros((len(both), 2)), np.ones((len(both), 2)), std, both, output)
            bound[std].append([r["bound"] for r in rows])
            for name in ESTIMATORS:
                estimator = build_baseline(config(name, seed, overrides))
                start = time.perf_counter()
                pred, true = estimator.predict_split(dm, "test", std)
                seconds[name].append(time.perf_counter() - start)
                dev[(name, std)].append(relative_deviation(pred, true).mean(axis=0))
                eff[(name, std)].append(
                    [r["efficiency"] or np.nan for r in bound_fields(pred, true, std, both, output)]
                )
    n = len(dm.rows("test"))
    print(
        f"test split of data=default, seat_spread 0.3, K = 1, {n} windows, seeds {args.seeds}, {args.threads} thread(s)"
    )
    print("mean relative deviation p1 / p2 [%] (efficiency p1 / p2: 1 = efficient)")
    print(f"{'':16s}" + "".join(f"{s:>22g}" for s in args.noise))
    for name in ESTIMATORS:
        cells = []
        for s in args.noise:
            m, e = np.mean(dev[(name, s)], axis=0) * 100, np.nanmean(eff[(name, s)], axis=0)
            cells.append(f"{m[0]:6.2f} / {m[1]:5.2f}" + (f" ({e[0]:.2f}/{e[1]:.2f})" if s > 0 else ""))
        print(f"{name:16s}" + "".join(f"{c:>22s}" for c in cells))
    cells = [f"{b[0]:6.2f} / {b[1]:5.2f}" for b in (np.mean(bound[s], axis=0) * 100 for s in args.noise)]
    print(f"{'Cramér-Rao bound':16s}" + "".join(f"{c:>22s}" for c in cells))
    print(f"seconds to fit {n} windows (median over noise levels and seeds):")
    for name in ESTIMATORS:
        print(f"  {name:8s} {np.median(seconds[name]):7.3f} s (max {np.max(seconds[name]):.3f} s)")
    print(f"  eiv / ls: {np.median(seconds['eiv']) / np.median(seconds['ls']):.1f}x")


if __name__ == "__main__":
    main()
