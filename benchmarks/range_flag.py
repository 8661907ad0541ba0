"""How near the trained range's edge the `range` flag marks an estimate (docs/predict.md, "Flags").

    python benchmarks/range_flag.py [RUN_DIR ...]
    python benchmarks/range_flag.py --train DIR

Without run directories it trains the runs it measures into a temporary folder (or into DIR, kept): fast_cnn
(bounded head) and paper_cnn (unbounded head) on data=tiny for 400 steps, as the tests' run, and fast_cnn on
data=default for 1500 steps. For each run, two sets of recordings simulated from its own data spec on roads it
never saw:

- in range: 20 roads x 20 seat masses uniform in [data.m3_min, data.m3_max], the run's road classes;
- outside: 10 roads (two of each class) at each of several seat masses below and above the range, simulated
  twice: by the run's own simulator, and as continuous motion (physics.exact, the exact solution between
  samples: another simulator, as an accelerometer records).

For each distance d (a fraction of the trained range's width in log p, the same in log m3), the share of
recordings whose estimate (K = 8 windows, the command's default) lies beyond the range or within d inside
it, in p1 or p2. The reference is the simulator's truth: the true m3 of every recording is known.
"""

import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from hybrid_sysid import load_estimator
from hybrid_sysid.data.dataset import generate_dataset
from hybrid_sysid.data.spec import DatasetSpec
from hybrid_sysid.physics import (
    continuous_recordings,
    road_amplitudes,
    road_phases,
    road_profiles,
    simulate,
    wave_numbers,
)

DISTANCES = (0.0, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1)
OUTSIDE = (0.5, 0.7, 0.8, 0.9, 1.1, 1.25, 1.5, 2.0)  # seat masses as factors of m3_min (< 1) or m3_max (> 1)
RUNS = {
    "fast_cnn data=tiny 400 steps": ["data=tiny", "trainer.max_steps=400"],
    "paper_cnn data=tiny 400 steps": ["data=tiny", "model=paper_cnn", "trainer.max_steps=400"],
    "fast_cnn data=default 1500 steps": ["trainer.max_steps=1500"],
}


def train(run_dir: Path, overrides: list[str]) -> Path:
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.training.run import train as train_run

    overrides = [*overrides, "trainer.progress_bar=false", "trainer.eval_every_n_steps=100"]
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
    train_run(cfg, run_dir, overrides)
    (run_dir / ".hydra").mkdir(exist_ok=True)
    OmegaConf.save(cfg, run_dir / ".hydra" / "config.yaml")
    return run_dir


def edge_distance(p: np.ndarray, p_min: np.ndarray, p_max: np.ndarray) -> np.ndarray:
    """(n,) the smaller distance of p1 and p2 to the nearest edge of the range, as a fraction of its log width;
    negative beyond the range."""
    u = np.log(p / p_min) / np.log(p_max / p_min)
    return np.minimum(u, 1 - u).min(axis=1)


def estimates(est, seat, body) -> np.ndarray:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = est.predict(seat, body, est.dt, windows=8)
    return table[["p1", "p2"]].to_numpy()


def measure(name: str, run_dir: Path) -> None:
    est = load_estimator(run_dir)
    spec = DatasetSpec.from_config(est.config)
    lo, hi = est.trained.p_min, est.trained.p_max
    inside = generate_dataset(replace(spec, seed=spec.seed + 1000, n_roads=20, n_masses=20))
    dist_in = edge_distance(estimates(est, inside.seat_acc, inside.body_acc), lo, hi)
    true_in = edge_distance(inside.params, lo, hi)
    print(f"\n## {name} ({run_dir})\n")
    print(f"m3 {spec.m3_min}-{spec.m3_max} kg; {len(dist_in)} in-range recordings of {spec.n_steps} steps")
    print("\n| d (of the log width) | in range flagged | true m3 within d of the edge |")
    print("| --- | --- | --- |")
    for d in DISTANCES:
        print(f"| {d:g} | {np.mean(dist_in < d):.1%} | {np.mean(true_in < d):.1%} |")
    classes = ("".join(spec.road_classes) * 10)[:10]
    amplitudes = road_amplitudes(classes, spec.n_waves)
    phases = road_phases(len(classes), spec.n_waves, np.random.default_rng(spec.seed + 2000))
    omegas = wave_numbers(spec.n_waves) * spec.speed
    road = road_profiles(classes, spec.n_steps, spec.dt, spec.speed, spec.n_waves, rng=spec.seed + 2000)  # same phases
    head = "| simulator | true m3 (kg) | estimated m3 from p1: median (min-max) | "
    print("\n" + head + " | ".join(f"d={d:g}" for d in DISTANCES) + " |")
    print("| --- | --- | --- | " + " | ".join("---" for _ in DISTANCES) + " |")
    for f in OUTSIDE:
        m3 = f * (spec.m3_min if f < 1 else spec.m3_max)
        masses = np.full(len(classes), m3)
        for simulator in ("run's", "continuous"):
            if simulator == "continuous":
                args = (amplitudes, phases, omegas, np.arange(len(classes)), masses, spec.n_steps, spec.dt)
                seat, body = continuous_recordings(*args, car=spec.car)
            else:
                seat, body = simulate(road, masses, spec.dt, car=spec.car, measurement=spec.measurement)
            p = estimates(est, seat, body)
            m = spec.car.c3 / p[:, 0]
            dist = edge_distance(p, lo, hi)
            shares = " | ".join(f"{np.mean(dist < d):.0%}" for d in DISTANCES)
            print(f"| {simulator} | {m3:g} | {np.median(m):.1f} ({m.min():.1f}-{m.max():.1f}) | {shares} |")


def main(args: list[str]) -> None:
    if args and args[0] != "--train":
        for run in args:
            measure(run, Path(run))
        return
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args[1] if args else tmp)
        for i, (name, overrides) in enumerate(RUNS.items()):
            measure(name, train(root / f"run{i}", overrides))


if __name__ == "__main__":
    main(sys.argv[1:])
