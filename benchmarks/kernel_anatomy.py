"""Where the generation kernel's time goes: its arithmetic, and the first touch of its output.

    python benchmarks/kernel_anatomy.py

Paper size (10,000 recordings x 6000 steps), two threads.
1. The kernel as the project compiles it (no fused multiply-add: bit-identical to the numpy reference) against
   the same source compiled with LLVM allowed to contract multiply + add into one instruction (a shorter
   dependency chain per step, different rounding). Both write into arrays already touched, alternating, 5
   timed rounds each after one warm-up; medians. Also: their float64 difference on 20 recordings.
2. The kernel writing into freshly allocated float32 arrays against the same arrays written a second time:
   the difference is the cost of first touching 0.96 GB.
"""

import time
import types

import numba
import numpy as np

from hybrid_sysid.physics import fused, road_profiles

N_ROADS, N_MASSES, N_STEPS, DT = 100, 100, 6000, 0.001


def contracted_kernel():
    """physics.fused._kernel and its _step, recompiled from their source with fastmath={"contract"}."""
    contract = {"contract"}
    module_globals = dict(fused.__dict__, _step=numba.njit(fastmath=contract)(fused._step.py_func))
    source = fused._kernel.py_func
    return numba.njit(parallel=True, fastmath=contract)(
        types.FunctionType(source.__code__, module_globals, source.__name__))


def run(kernel, roads, road_of, m3, out):
    original = fused._compiled_kernel
    fused._compiled_kernel = lambda: kernel
    try:
        t0 = time.perf_counter()
        fused.simulate_recordings(roads, road_of, m3, DT, out=out)
        return time.perf_counter() - t0
    finally:
        fused._compiled_kernel = original


def main():
    roads = road_profiles(["C"] * N_ROADS, N_STEPS, DT, 20.0, rng=1)
    road_of = np.repeat(np.arange(N_ROADS), N_MASSES)
    m3 = np.random.default_rng(0).integers(50, 201, size=N_ROADS * N_MASSES).astype(float)
    kernels = {"exact (as the project compiles it)": fused._kernel, "fused multiply-add allowed": contracted_kernel()}

    few = tuple(np.empty((20, N_STEPS)) for _ in range(4))
    exact64 = [a.copy() for a in fused.simulate_recordings(roads, road_of[::500], m3[::500], DT, out=few)]
    run(kernels["fused multiply-add allowed"], roads, road_of[::500], m3[::500], few)
    diff = [np.abs(a - b).max() / np.abs(b).max() for a, b in zip(few, exact64)]

    out = tuple(np.ones((len(m3), N_STEPS), np.float32) for _ in range(4))
    times = {name: [] for name in kernels}
    for r in range(6):
        order = list(kernels.items())
        for name, kernel in (order if r % 2 == 0 else order[::-1]):
            t = run(kernel, roads, road_of, m3, out)
            if r:
                times[name].append(t)
    print(f"1. kernel, {N_ROADS * N_MASSES} recordings x {N_STEPS} steps, {numba.get_num_threads()} threads, "
          "output already touched (5 alternating rounds):")
    for name, ts in times.items():
        print(f"   {name}: median {np.median(ts):.3f} s ({' / '.join(f'{t:.3f}' for t in ts)})")
    print("   float64 rel. difference, fused multiply-add vs exact (seat, body, rel. vel., rel. disp.): "
          + ", ".join(f"{d:.1e}" for d in diff))
    del out

    fresh, again = [], []
    for _ in range(3):
        out = tuple(np.empty((len(m3), N_STEPS), np.float32) for _ in range(4))
        fresh.append(run(fused._kernel, roads, road_of, m3, out))
        again.append(run(fused._kernel, roads, road_of, m3, out))
        del out
    print(f"2. exact kernel into new arrays {' / '.join(f'{t:.3f}' for t in fresh)} s; into the same arrays "
          f"again {' / '.join(f'{t:.3f}' for t in again)} s")


if __name__ == "__main__":
    main()
