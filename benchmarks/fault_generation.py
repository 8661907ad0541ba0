"""Generating a dataset with every recording fault on against the plain dataset; and the fractional delay's
accuracy (docs/faults.md quotes both).

    python benchmarks/fault_generation.py [--rounds 9] [--roads 40 --masses 50 --steps 1200]

Timing: data=default's size (40 roads x 50 masses x 1200 steps at 5 ms), ``generate_dataset`` plain and with
sensor.gain_spread=0.03, sensor.skew_max=0.01, sensor.lowpass_range_hz=[20, 40] and car.seat_hardening=35000
(every preset at once), and each fault alone. All in one process after a first call of each (numba compiles its
kernels at the first call), the variants interleaved round by round so the machine's drift hits them alike; the
best of --rounds each. The issue's goal: every fault on within 1.5x of the plain time.

Accuracy: ``physics.sensors.fractional_delay`` of a sum of 40 sines below a fraction of the Nyquist frequency,
against the analytic shift, the largest error over six delays (-1.5 .. 9.8 samples) relative to the signal's
peak, away from the edges (half_width + 10 samples at each end).
"""

import argparse
import time

import numpy as np
from machine import cpu_name, load_average

from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.dataset import generate_dataset
from hybrid_sysid.physics import QuarterCar, SensorFaults, fractional_delay

HARD = QuarterCar(seat_hardening=35000.0)


def variants(size: dict) -> dict:
    return {
        "plain": DatasetSpec(**size),
        "every fault": DatasetSpec(
            **size, car=HARD, sensor=SensorFaults(gain_spread=0.03, skew_max=0.01, lowpass_range_hz=(20.0, 40.0))
        ),
        "gain": DatasetSpec(**size, sensor=SensorFaults(gain_spread=0.03)),
        "skew": DatasetSpec(**size, sensor=SensorFaults(skew_max=0.01)),
        "lowpass": DatasetSpec(**size, sensor=SensorFaults(lowpass_range_hz=(20.0, 40.0))),
        "hardening": DatasetSpec(**size, car=HARD),
    }


def timing(size: dict, rounds: int) -> None:
    specs = variants(size)
    for spec in specs.values():
        generate_dataset(spec)  # compiles
    times = {name: [] for name in specs}
    for _ in range(rounds):
        for name, spec in specs.items():
            start = time.perf_counter()
            generate_dataset(spec)
            times[name].append(time.perf_counter() - start)
    plain = min(times["plain"])
    print(f"{'dataset':<12} {'best s':>8} {'ratio':>6}")
    for name, ts in times.items():
        print(f"{name:<12} {min(ts):8.4f} {min(ts) / plain:6.2f}")


def accuracy() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(4000)
    delays = np.array([0.37, -1.5, 2.25, 0.1, -0.49, 9.8])
    widths = (8, 12, 16, 24, 32)
    print("fractional delay, error / peak; rows: content up to this fraction of Nyquist; columns: half_width")
    print(f"{'':>6}" + "".join(f"{w:>9}" for w in widths))
    for top in (0.2, 0.4, 0.5, 0.6):
        freq, phase = rng.uniform(0, top / 2, 40), rng.uniform(0, 2 * np.pi, 40)

        def signal(times, freq=freq, phase=phase):
            return np.sin(2 * np.pi * freq[:, None] * times[None, :] + phase[:, None]).sum(axis=0)

        x = np.tile(signal(t), (len(delays), 1))
        exact = np.stack([signal(t - d) for d in delays])
        row = []
        for w in widths:
            edge = w + 10
            err = np.abs(fractional_delay(x, delays, w) - exact)[:, edge:-edge].max() / np.abs(exact).max()
            row.append(f"{err:9.1e}")
        print(f"{top:>6}" + "".join(row))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--roads", type=int, default=40)
    ap.add_argument("--masses", type=int, default=50)
    ap.add_argument("--steps", type=int, default=1200)
    args = ap.parse_args()
    print(f"CPU: {cpu_name()}; load average before: {load_average()}")
    timing(dict(n_roads=args.roads, n_masses=args.masses, n_steps=args.steps), args.rounds)
    print(f"load average after: {load_average()}")
    accuracy()


if __name__ == "__main__":
    main()
