"""The share a fit-free network should take beside the anchored estimator, noise level by noise level.

    python benchmarks/partner_share.py --anchored RUN [RUN ...] --cnn RUN [RUN ...] [--data-seed 7] [--windows 1200]

--anchored: runs of model=anchored (experiment=anchored's clean anchored_cross_segment rows, blended); --cnn: runs
of label-free fast_cnn (its cnn_cross_segment rows), paired in order. Both are evaluated, as loaded, on the windows
of benchmarks/anchored_blend.py (a dataset no run saw), at six noise levels. For each level: each alone, the share
m of the fast_cnn estimate in log p (p_anchored^(1 - m) p_cnn^m) with the lowest mean of p1's and p2's mean
relative deviation, that mix's deviations, and the median seat noise sigma the likelihood fit estimates. One
thread; a few minutes a pair. This chose the partner's form (model.net.partner): a share that grows with sigma.
"""

import argparse

import numpy as np
import torch
from anchored_blend import windows

from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.inference.loading import load_estimator
from hybrid_sysid.runs.rundir import RunDir

LEVELS = (0.003, 0.01, 0.02, 0.03, 0.05, 0.1)
SHARES = np.linspace(0, 1, 21)


def deviation(p, truth):
    return 100 * np.abs(p / truth - 1).mean(axis=0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--anchored", nargs="+", required=True)
    ap.add_argument("--cnn", nargs="+", required=True)
    ap.add_argument("--data-seed", type=int, default=7)
    ap.add_argument("--windows", type=int, default=1200)
    args = ap.parse_args()
    if len(args.anchored) != len(args.cnn):
        ap.error("--anchored and --cnn pair runs in order: give as many of each")
    torch.set_num_threads(1)
    found = {}  # level -> [(p_anchored, p_cnn, sigma, truth) per pair]
    for anchored_run, cnn_run in zip(args.anchored, args.cnn):
        anchored, cnn = (load_estimator(r).net.eval() for r in (anchored_run, cnn_run))
        rng = np.random.default_rng(123)  # benchmarks/anchored_blend.py's windows and noise
        cfg = RunDir(anchored_run).saved_config("run")
        seat0, body0, truth, spec = windows(cfg, args.data_seed, args.windows, rng)
        fit = ErrorsInVariablesFit(prior=dict(cfg.model.net.prior), dt=spec.dt)  # the partner's sigma: its ML fit
        for std in LEVELS:
            seat = seat0 + std * rng.standard_normal(seat0.shape)
            body = body0 + std * rng.standard_normal(body0.shape)
            signals = torch.from_numpy(np.stack([seat, body], axis=1)).float()
            with torch.no_grad():
                p_a, p_c = (net(signals).double().numpy() for net in (anchored, cnn))
            x = signals.double().numpy()
            raw = fit.fit_with_ml(x[:, 0], x[:, 1], spec.dt, spec.measurement)[3]
            sigma = np.sqrt(raw[2].ml.sigma2)
            found.setdefault(std, []).append((p_a, p_c, sigma, truth))
        print(f"{anchored_run} + {cnn_run}: done", flush=True)
    print(f"\n{len(args.anchored)} pairs, {args.windows} windows of data.seed={args.data_seed}; p1 / p2 in %\n")
    print("| noise | anchored | fast_cnn | best share | its mix | median sigma |")
    print("| --- | --- | --- | --- | --- | --- |")
    for std, pairs in found.items():

        def mean(f, pairs=pairs):
            return np.mean([f(*pair) for pair in pairs], axis=0)

        alone = [mean(lambda a, c, s, t, i=i: deviation((a, c)[i], t)) for i in (0, 1)]
        mixes = [mean(lambda a, c, s, t, m=m: deviation(a ** (1 - m) * c**m, t)) for m in SHARES]
        best = int(np.argmin([m.sum() for m in mixes]))
        sigma = np.nanmedian(np.concatenate([s for _, _, s, _ in pairs]))
        cells = [f"{v[0]:.2f} / {v[1]:.2f}" for v in (*alone, mixes[best])]
        print(f"| {std:g} | {cells[0]} | {cells[1]} | {SHARES[best]:.2f} | {cells[2]} | {sigma:.4f} |")


if __name__ == "__main__":
    main()
