"""Seat and body acceleration RMS per road class on data=default's settings (amplitudes by the paper's eq. 3), and
the signal-to-noise ratio that sensor noise of a given std leaves (docs/noise.md quotes this script's output).

    python benchmarks/signal_levels.py [--roads 20] [--noise 0.01]

data=default: 1200 steps at dt = 5 ms, 15 m/s, 300 waves, consistent recording, m3 uniform in [50, 200] kg.
The RMS is over every step of every recording of a class (``--roads`` roads per class, one random mass each).
"""

import argparse

import numpy as np

from hybrid_sysid.physics import road_profiles, simulate


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roads", type=int, default=20)
    ap.add_argument("--noise", type=float, default=0.01)
    args = ap.parse_args()
    dt, n_steps, speed = 0.005, 1200, 15.0
    rng = np.random.default_rng(0)
    print(f"{args.roads} roads per class, data=default settings; noise std {args.noise} m/s^2")
    print("| class | seat RMS [m/s^2] | body RMS [m/s^2] | seat RMS / noise std |")
    print("| --- | ---: | ---: | ---: |")
    for cls in "ABCDE":
        road = road_profiles([cls] * args.roads, n_steps, dt, speed, 300, rng)
        masses = rng.integers(50, 201, size=args.roads).astype(float)
        seat, body = simulate(road, masses, dt, measurement="consistent")
        s, b = np.sqrt(np.mean(seat**2)), np.sqrt(np.mean(body**2))
        print(f"| {cls} | {s:.3g} | {b:.3g} | {s / args.noise:.3g} |")


if __name__ == "__main__":
    main()
