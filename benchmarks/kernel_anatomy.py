"""Where the generation kernel's time goes: arithmetic on one core, and the first touch of the output.

    python benchmarks/kernel_anatomy.py

1. Arithmetic: the kernel's step (physics.fused._step) for two interleaved recordings over 6000 steps, one
   thread, output arrays already touched; nanoseconds per recording-step, best of 5. Compiled twice from the
   same source: as the project compiles it (no fused multiply-add: bit-identical to the numpy reference), and
   with LLVM allowed to contract multiply + add into one instruction (shorter dependency chain, different
   rounding), whose float64 difference from the exact version is printed too.
2. Memory: the whole kernel on the paper-size dataset (10,000 recordings x 6000 steps, two threads) writing
   into freshly allocated float32 arrays against the same arrays written a second time; the difference is
   the cost of first touching 0.96 GB.
"""

import time

import numba
import numpy as np

from hybrid_sysid.physics import QuarterCar, fused, road_profiles


def pair_loop(step, fastmath):
    @numba.njit(fastmath=fastmath, boundscheck=False)
    def run(road_i, road_j, p1_i, p2_i, p1_j, p2_j, dt, c, outs):
        si, bi, vi, di, sj, bj, vj, dj = outs
        state_i = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        state_j = state_i
        for k in range(si.shape[0]):
            state_i, si[k], bi[k], vi[k], di[k] = step(state_i, road_i[k], p1_i, p2_i, dt, c, True)
            state_j, sj[k], bj[k], vj[k], dj[k] = step(state_j, road_j[k], p1_j, p2_j, dt, c, True)
    return run


def coefficients(car=QuarterCar()):
    return (-car.c2 / car.m1, car.c2 / car.m1, car.k2 / car.m1, -(car.k1 + car.k2) / car.m1, car.k1 / car.m1,
            car.c3 / car.m2, -(car.c2 + car.c3) / car.m2, car.c2 / car.m2, car.k3 / car.m2,
            -(car.k2 + car.k3) / car.m2, car.k2 / car.m2, car.c2 / car.m2)


def arithmetic(n_steps=6000, dt=0.001):
    roads = road_profiles(["C", "E"], n_steps, dt, 20.0, rng=0)
    (p1_i, p1_j), (p2_i, p2_j) = QuarterCar().parameters(np.array([60.0, 180.0]))
    args = (roads[0], roads[1], p1_i, p2_i, p1_j, p2_j, dt, coefficients())
    contract = {"contract"}
    variants = {"exact (as compiled in the project)": pair_loop(fused._step, False),
                "fused multiply-add allowed": pair_loop(numba.njit(fastmath=contract)(fused._step.py_func), contract)}
    results = {}
    for name, run in variants.items():
        out64 = tuple(np.zeros(n_steps) for _ in range(8))
        run(*args, out64)
        out32 = tuple(np.ones(n_steps, np.float32) for _ in range(8))
        best = np.inf
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(100):
                run(*args, out32)
            best = min(best, (time.perf_counter() - t0) / (100 * 2 * n_steps))
        results[name] = (best, out64)
    exact = results["exact (as compiled in the project)"][1]
    print("1. arithmetic, one thread, two recordings interleaved, outputs already touched:")
    for name, (best, out) in results.items():
        diff = [np.abs(a - b).max() / np.abs(b).max() for a, b in zip(out[:4], exact[:4])]
        print(f"   {name}: {best * 1e9:.1f} ns per recording-step; float64 rel. difference from exact "
              f"(seat, body, rel. vel., rel. disp.): {', '.join(f'{d:.1e}' for d in diff)}")


def first_touch(n_roads=100, n_masses=100, n_steps=6000, dt=0.001):
    roads = road_profiles(["C"] * n_roads, n_steps, dt, 20.0, rng=1)
    road_of = np.repeat(np.arange(n_roads), n_masses)
    m3 = np.random.default_rng(0).integers(50, 201, size=n_roads * n_masses).astype(float)
    fused.simulate_recordings(roads[:1, :10], road_of[:2] * 0, m3[:2], dt)  # compile or load from cache
    fresh, again = [], []
    for _ in range(3):
        out = tuple(np.empty((len(m3), n_steps), np.float32) for _ in range(4))
        t0 = time.perf_counter()
        fused.simulate_recordings(roads, road_of, m3, dt, out=out)
        t1 = time.perf_counter()
        fused.simulate_recordings(roads, road_of, m3, dt, out=out)
        t2 = time.perf_counter()
        fresh.append(t1 - t0)
        again.append(t2 - t1)
        del out
    print(f"2. kernel, paper size, {numba.get_num_threads()} threads: into new arrays "
          f"{' / '.join(f'{t:.3f}' for t in fresh)} s; into the same arrays again "
          f"{' / '.join(f'{t:.3f}' for t in again)} s")


if __name__ == "__main__":
    arithmetic()
    first_touch()
