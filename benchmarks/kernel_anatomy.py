"""Where the generation kernel's time goes, and the designs it was chosen over.

    python benchmarks/kernel_anatomy.py [--rounds 5]

Paper size (10,000 recordings x 6000 steps), two threads, float32 output.
1. The project's kernel (physics/fused.py: 16 recordings stepped side by side, SIMD across them, results
   written eight steps at a time from a tile buffer) against
   - the previous design, kept here: two recordings per iteration, scalar, each result stored as it comes
     (latency bound: one recording's step is a chain of ~20 dependent operations);
   - the project's kernel with its arithmetic only (results of the last step written): what the arithmetic
     costs without the output;
   - the project's kernel copying its tile out with numba's plain loop instead of column_store's vector
     stores;
   - the project's kernel compiled with LLVM allowed to contract multiply + add (fused multiply-add: different
     rounding, so not used; its float64 difference from the exact kernel is printed).
   All write into arrays already touched, in alternating order, --rounds timed rounds after a warm-up; medians.
   Each candidate is checked bit-identical to the project's kernel in float64 (both measurement models) first,
   except the fused multiply-add one.
2. The project's kernel writing into freshly allocated arrays against the same arrays written again: the
   difference is the cost of first touching 0.96 GB.
"""

import argparse
import time
import types

import numba
import numpy as np

from hybrid_sysid.physics import fused, road_profiles

N_ROADS, N_MASSES, N_STEPS, DT = 100, 100, 6000, 0.001


@numba.njit(fastmath=False)
def _pair_step(state, r, p1, p2, dt, coef, consistent):
    a_uu, a_uv, a_uy, a_ux, a_ur, b_vw, b_vv, b_vu, b_vz, b_vy, b_vx, c2m2 = coef
    u, v, w, x, y, z, s_rel, q_rel = state
    seat12 = -p1 * (w - v) - p2 * (z - y)
    body12 = b_vw * (w - v) + c2m2 * (u - v) + b_vz * (z - y) + b_vx * (x - y)
    acc_u = a_uu * u + a_uv * v + a_uy * y + a_ux * x + a_ur * r
    u = u + dt * acc_u
    acc_v = b_vw * w + b_vv * v + b_vu * u + b_vz * z + b_vy * y + b_vx * x
    v = v + dt * acc_v
    acc_w = -p1 * (w - v) - p2 * (z - y)
    w = w + dt * acc_w
    x = x + dt * u
    y = y + dt * v
    z = z + dt * w
    seat = acc_w if consistent else seat12
    body = acc_v if consistent else body12
    vel_rel = s_rel * dt
    q_rel += vel_rel
    vel_rel = vel_rel - dt * body if consistent else vel_rel
    s_rel += seat - body
    return (u, v, w, x, y, z, s_rel, q_rel), seat, body, vel_rel, q_rel * dt


@numba.njit(parallel=True, fastmath=False)
def pair_kernel(roads, road_of, p1s, p2s, dt, coef, consistent, seat_out, body_out, vel_out, disp_out):
    """The project's kernel until 2026-11-22: two recordings per iteration, scalar."""
    n_rec, n_steps = seat_out.shape
    c = (coef[0], coef[1], coef[2], coef[3], coef[4], coef[5], coef[6], coef[7], coef[8], coef[9], coef[10],
         coef[11])
    for pair in numba.prange((n_rec + 1) // 2):
        i = 2 * pair
        j = min(i + 1, n_rec - 1)
        road_i, road_j = roads[road_of[i]], roads[road_of[j]]
        state_i = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        state_j = state_i
        for k in range(n_steps):
            state_i, seat, body, vel, disp = _pair_step(state_i, road_i[k], p1s[i], p2s[i], dt, c, consistent)
            seat_out[i, k], body_out[i, k], vel_out[i, k], disp_out[i, k] = seat, body, vel, disp
            state_j, seat, body, vel, disp = _pair_step(state_j, road_j[k], p1s[j], p2s[j], dt, c, consistent)
            seat_out[j, k], body_out[j, k], vel_out[j, k], disp_out[j, k] = seat, body, vel, disp


def variant(fastmath=False, arithmetic_only=False, scalar_copy=False):
    """physics.fused._kernel recompiled from its source: with fused multiply-add allowed, writing only the
    last step's results (every store of the output loop skipped but the last tile's), or copying the tile out
    with numba's plain loop (its scalar tail loop for every step) instead of column_store's vector stores."""
    source = fused._kernel.py_func
    namespace = dict(fused.__dict__)
    if arithmetic_only or scalar_copy:
        import inspect
        import textwrap
        text = textwrap.dedent(inspect.getsource(source)).split("\n", 1)[1]  # drop the decorator
        old, new = (("            for lane in range(n_lanes):\n                i = first + lane",
                     "            for lane in range(n_lanes if t0 + n_t == n_steps else 0):\n"
                     "                i = first + lane") if arithmetic_only else
                    ("n_vec = n_t - n_t % WIDTH", "n_vec = 0"))
        assert old in text, "fused._kernel's output loop changed"
        exec(text.replace(old, new), namespace)
        source = namespace["_kernel"]
    return numba.njit(parallel=True, fastmath={"contract"} if fastmath else False)(
        types.FunctionType(source.__code__, namespace, source.__name__))


def run(kernel, roads, road_of, m3, out, measurement="consistent"):
    original = fused._compiled_kernel
    fused._compiled_kernel = lambda: kernel
    try:
        t0 = time.perf_counter()
        fused.simulate_recordings(roads, road_of, m3, DT, out=out, measurement=measurement)
        return time.perf_counter() - t0
    finally:
        fused._compiled_kernel = original


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    roads = road_profiles(["C"] * N_ROADS, N_STEPS, DT, 20.0, rng=1)
    road_of = np.repeat(np.arange(N_ROADS), N_MASSES)
    m3 = np.random.default_rng(0).integers(50, 201, size=N_ROADS * N_MASSES).astype(float)
    kernels = {"project kernel (16 lanes, SIMD, tile buffer)": fused._kernel,
               "previous kernel (two recordings per iteration, scalar)": pair_kernel,
               "project kernel, arithmetic only (last step written)": variant(arithmetic_only=True),
               "project kernel, tile copied out by a plain loop (scalar stores)": variant(scalar_copy=True),
               "project kernel, fused multiply-add allowed": variant(fastmath=True)}

    few = slice(3, len(m3), 499)  # 21 recordings: a partial block of lanes
    for measurement in ("consistent", "paper"):
        exact = tuple(np.empty((len(m3[few]), N_STEPS)) for _ in range(4))
        run(fused._kernel, roads, road_of[few], m3[few], exact, measurement)
        for name, kernel in list(kernels.items())[1:]:
            got = tuple(np.empty_like(a) for a in exact)
            run(kernel, roads, road_of[few], m3[few], got, measurement)
            if "arithmetic only" in name:
                got, exact_cmp = [a[:, -1] for a in got], [a[:, -1] for a in exact]
            else:
                exact_cmp = exact
            if "multiply-add" in name:
                diff = [np.abs(a - b).max() / np.abs(b).max() for a, b in zip(got, exact_cmp)]
                print(f"{name}, {measurement}: float64 rel. difference from the exact kernel (seat, body, "
                      "rel. vel., rel. disp.): " + ", ".join(f"{d:.1e}" for d in diff))
            else:
                same = all(np.array_equal(a, b) for a, b in zip(got, exact_cmp))
                print(f"{name}, {measurement}: bit-identical to the project kernel in float64: {same}")

    out = tuple(np.ones((len(m3), N_STEPS), np.float32) for _ in range(4))
    times = {name: [] for name in kernels}
    for r in range(args.rounds + 1):
        order = list(kernels.items())
        for name, kernel in (order if r % 2 == 0 else order[::-1]):
            t = run(kernel, roads, road_of, m3, out)
            if r:
                times[name].append(t)
    print(f"1. kernel, {N_ROADS * N_MASSES} recordings x {N_STEPS} steps, {numba.get_num_threads()} threads, "
          f"float32 output already touched ({args.rounds} alternating rounds):")
    for name, ts in times.items():
        print(f"   {name}: median {np.median(ts):.3f} s ({' / '.join(f'{t:.3f}' for t in ts)})")
    del out

    fresh, again = [], []
    for _ in range(3):
        out = tuple(np.empty((len(m3), N_STEPS), np.float32) for _ in range(4))
        fresh.append(run(fused._kernel, roads, road_of, m3, out))
        again.append(run(fused._kernel, roads, road_of, m3, out))
        del out
    print(f"2. project kernel into new arrays {' / '.join(f'{t:.3f}' for t in fresh)} s; into the same arrays "
          f"again {' / '.join(f'{t:.3f}' for t in again)} s")


if __name__ == "__main__":
    main()
