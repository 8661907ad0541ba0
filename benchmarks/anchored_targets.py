"""The targets of experiment=anchored, checked on its sweep with their uncertainty (docs/results_notes.md).

    python benchmarks/anchored_targets.py SWEEP_DIR

Per cell (fault, K, noise level, parameter) of the test split: each estimator's mean relative deviation over
seeds with the 95% Student t interval of that mean, and the two-sided Wilcoxon signed-rank p-value over the
recordings (their deviations averaged over seeds) against per-window least squares. A bound is met when the
interval's upper end lies below it; "below" another row when the mean is lower and the paired p < 0.05.
"""

import math
import sys

import numpy as np

from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.stats import paired_p, t_interval
from hybrid_sysid.report.summary import tested_table

LABEL_FREE = ("anchored_label_free", "anchored_cross_segment")
NETWORKS = ("cnn_labelled", "cnn_label_free", "cnn_cross_segment")
BOUNDS = {  # (fault, noise, parameter) -> the bound in percent, K = 1
    ("clean", 0.0, "p1"): 0.01,
    ("clean", 0.0, "p2"): 0.01,
    ("clean", 0.01, "p1"): 5.0,
    ("clean", 0.01, "p2"): 1.5,
    ("clean", 0.03, "p1"): 11.0,
    ("clean", 0.03, "p2"): 5.3,
    ("skewed", 0.0, "p1"): 5.7,
    ("hardening", 0.0, "p2"): 3.9,
}


def main(sweep: str) -> None:
    root, df = load_runs(sweep)
    table = tested_table(df, root)
    paired = table.attrs.get("paired", {})
    per_seed = df[(df.split == "test") & (df.status == "completed")]

    def cell(fault, est, k, noise, param):
        rows = per_seed[
            (per_seed.fault == fault)
            & (per_seed.estimator == est)
            & (per_seed.windows.astype(int) == k)
            & (per_seed.noise_std.astype(float) == noise)
            & (per_seed.parameter == param)
        ]
        v = 100 * rows.mean_rel_dev.astype(float).to_numpy()
        return (np.nan, (np.nan, np.nan), 0) if len(v) == 0 else (v.mean(), t_interval(v), len(v))

    def p_against(fault, a, b, k, noise, param):
        return paired_p(paired, (fault, a, k), (fault, b, k), (noise, param))

    faults = list(dict.fromkeys(per_seed.fault))
    levels = sorted(set(per_seed.noise_std.astype(float)))
    for fault in faults:
        for k in sorted(set(per_seed.windows.astype(int))):
            print(f"\n{fault}, K = {k}: mean [95% interval] (seeds), p against ls")
            for est in dict.fromkeys(per_seed[per_seed.fault == fault].estimator):
                parts = []
                for noise in levels:
                    for param in ("p1", "p2"):
                        m, (lo, hi), n = cell(fault, est, k, noise, param)
                        p = p_against(fault, est, "ls", k, noise, param)
                        parts.append(f"{m:.2f} [{lo:.2f}, {hi:.2f}]" + ("" if p is None else f" p={p:.1g}"))
                print(f"  {est:24s} " + " | ".join(parts))
    print("\nTargets (K = 1 unless said):")
    for (fault, noise, param), bound in BOUNDS.items():
        for est in LABEL_FREE:
            m, (lo, hi), n = cell(fault, est, 1, noise, param)
            ls = cell(fault, "ls", 1, noise, param)[0]
            p = p_against(fault, est, "ls", 1, noise, param)
            met = "met" if hi <= bound else "not met"
            print(
                f"  {fault} noise {noise:g} {param} <= {bound}: {est} {m:.3f} [{lo:.3f}, {hi:.3f}] {met}; "
                f"LS {ls:.3f}, p {p}"
            )
    for k in (1, 8):
        for noise in levels[1:] if k == 1 else levels:
            for param in ("p1", "p2"):
                for est in LABEL_FREE:
                    m = cell("clean", est, k, noise, param)[0]
                    best = min(NETWORKS, key=lambda e: cell("clean", e, k, noise, param)[0])
                    vs_ls, vs_net = (p_against("clean", est, o, k, noise, param) for o in ("ls", best))
                    ls, net = cell("clean", "ls", k, noise, param)[0], cell("clean", best, k, noise, param)[0]
                    below_ls = m < ls and vs_ls is not None and vs_ls < 0.05
                    below_net = m < net and vs_net is not None and vs_net < 0.05
                    print(
                        f"  K={k} noise {noise:g} {param} {est}: {m:.2f}; "
                        f"LS {ls:.2f} (p {vs_ls or math.nan:.1g}, below: {below_ls}); "
                        f"best network {best} {net:.2f} (p {vs_net or math.nan:.1g}, below: {below_net})"
                    )


if __name__ == "__main__":
    main(sys.argv[1])
