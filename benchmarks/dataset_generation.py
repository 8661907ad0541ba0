"""How long the paper-size dataset (100 roads x 100 masses x 6000 steps) takes to simulate, and its memory.

    python benchmarks/dataset_generation.py [--roads 100 --masses 100 --steps 6000]

Prints wall time per stage (roads, simulation + re-integration, total), the dataset's size in memory and the
process's peak resident memory (which includes Python, numpy and torch imports: about 0.1 GB).
"""

import argparse
import resource
import time

import numpy as np

from hybrid_sysid.data import DatasetSpec, generate_dataset
from hybrid_sysid.physics import road_profiles


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roads", type=int, default=100)
    ap.add_argument("--masses", type=int, default=100)
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--dt", type=float, default=0.001)
    args = ap.parse_args()
    spec = DatasetSpec(n_roads=args.roads, n_masses=args.masses, n_steps=args.steps, dt=args.dt)

    t0 = time.perf_counter()
    road_profiles(["C"] * args.roads, args.steps, args.dt, spec.speed, rng=0)
    t_roads = time.perf_counter() - t0

    t0 = time.perf_counter()
    ds = generate_dataset(spec)
    t_total = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB -> GiB on Linux
    assert np.isfinite(ds.seat_acc).all()
    print(f"dataset {args.roads} roads x {args.masses} masses x {args.steps} steps = {len(ds)} recordings")
    print(f"roads (shared sine basis, two matmuls): {t_roads:.3f} s")
    print(f"whole generation (roads + simulation + re-integration + float32 copy): {t_total:.2f} s")
    print(f"dataset in memory: {ds.nbytes / 2**30:.3f} GiB; process peak RSS: {peak:.3f} GiB")


if __name__ == "__main__":
    main()
