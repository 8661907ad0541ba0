"""Why the generation kernel steps recordings one (pair) at a time instead of vectorising across them.

    python benchmarks/vectorised_kernel.py [--rounds 3]    (~10 min, almost all numba compiling the lane kernels)

Paper size (10,000 recordings x 6000 steps), two threads, output already touched. Compares, alternating:
1. the project's kernel (physics/fused.py: two recordings per iteration, latency bound);
2. a lane-parallel kernel: blocks of L recordings stepped together so LLVM vectorises across them, results
   buffered lane-major for TB steps, then copied into the recording-major dataset (a transposition);
3. the same lane-parallel kernel writing only its final step (its arithmetic, without the transposition);
and the floors of writing the 0.96 GB output: a plain parallel fill, and copies of the same size from a block
buffer laid out row by row (contiguous) or lane-major (transposing), with no arithmetic at all.
The lane-parallel kernel is checked bit-identical to the project's in float64 (both measurement models).
"""

import argparse
import time

import numba
import numpy as np

from hybrid_sysid.physics import fused, road_profiles

N_ROADS, N_MASSES, N_STEPS, DT = 100, 100, 6000, 0.001


def lane_kernel(L, TB, write_back=True):
    """A kernel with physics.fused._kernel's signature and arithmetic (same operations, same order per lane)."""

    @numba.njit(parallel=True, fastmath=False)
    def kernel(roads, road_of, p1s, p2s, dt, coef, consistent, seat_out, body_out, vel_out, disp_out):
        n_rec, n_steps = seat_out.shape
        a_uu, a_uv, a_uy, a_ux, a_ur = coef[0], coef[1], coef[2], coef[3], coef[4]
        b_vw, b_vv, b_vu, b_vz, b_vy, b_vx, c2m2 = coef[5], coef[6], coef[7], coef[8], coef[9], coef[10], coef[11]
        for b in numba.prange((n_rec + L - 1) // L):
            r0 = b * L
            S = np.zeros((10, L))  # one state array: more separate arrays exceed LLVM's alias-check budget
            rows = np.empty(L, np.int64)
            for l in range(L):
                i = min(r0 + l, n_rec - 1)
                rows[l] = road_of[i]
                S[8, l], S[9, l] = p1s[i], p2s[i]
            R = np.empty((TB, L))
            B = np.empty((4, TB, L), seat_out.dtype)
            for t0 in range(0, n_steps, TB):
                nt = min(TB, n_steps - t0)
                for kk in range(nt):
                    for l in range(L):
                        R[kk, l] = roads[rows[l], t0 + kk]
                for kk in range(nt):
                    for l in range(L):  # the vectorised loop
                        u, v, w, x, y, z, s_rel, q_rel = S[0, l], S[1, l], S[2, l], S[3, l], S[4, l], S[5, l], \
                            S[6, l], S[7, l]
                        p1, p2, r = S[8, l], S[9, l], R[kk, l]
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
                        S[0, l], S[1, l], S[2, l], S[3, l], S[4, l], S[5, l], S[6, l], S[7, l] = \
                            u, v, w, x, y, z, s_rel, q_rel
                        B[0, kk, l], B[1, kk, l], B[2, kk, l], B[3, kk, l] = seat, body, vel_rel, q_rel * dt
                last = nt if write_back else (nt if t0 + nt == n_steps else 0)
                for l in range(min(L, n_rec - r0)):  # lane-major buffer -> recording-major rows
                    i = r0 + l
                    for kk in range(nt - last, nt):
                        seat_out[i, t0 + kk] = B[0, kk, l]
                    for kk in range(nt - last, nt):
                        body_out[i, t0 + kk] = B[1, kk, l]
                    for kk in range(nt - last, nt):
                        vel_out[i, t0 + kk] = B[2, kk, l]
                    for kk in range(nt - last, nt):
                        disp_out[i, t0 + kk] = B[3, kk, l]

    return kernel


def copy_floor(L, TB, transpose):
    """Copy the output's size from a block buffer into the four channels: lane-major (a transposition, as the
    lane kernel must) or row by row (contiguous); no arithmetic."""

    @numba.njit(parallel=True)
    def copy(o0, o1, o2, o3):
        n, m = o0.shape
        for b in numba.prange(n // L):
            r0 = b * L
            B = np.ones((4, TB, L), np.float32)
            C = np.ones((4, L, TB), np.float32)
            for t0 in range(0, m, TB):
                nt = min(TB, m - t0)
                B[0, 0, 0] += 1.0
                C[0, 0, 0] += 1.0
                for l in range(L):
                    i = r0 + l
                    if transpose:
                        for kk in range(nt):
                            o0[i, t0 + kk] = B[0, kk, l]
                        for kk in range(nt):
                            o1[i, t0 + kk] = B[1, kk, l]
                        for kk in range(nt):
                            o2[i, t0 + kk] = B[2, kk, l]
                        for kk in range(nt):
                            o3[i, t0 + kk] = B[3, kk, l]
                    else:
                        for kk in range(nt):
                            o0[i, t0 + kk] = C[0, l, kk]
                        for kk in range(nt):
                            o1[i, t0 + kk] = C[1, l, kk]
                        for kk in range(nt):
                            o2[i, t0 + kk] = C[2, l, kk]
                        for kk in range(nt):
                            o3[i, t0 + kk] = C[3, l, kk]

    return copy


@numba.njit(parallel=True)
def fill(o0, o1, o2, o3, value):
    for i in numba.prange(o0.shape[0]):
        for k in range(o0.shape[1]):
            o0[i, k] = value
            o1[i, k] = value
            o2[i, k] = value
            o3[i, k] = value


def simulate(kernel, roads, road_of, m3, out, measurement="consistent"):
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
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    roads = road_profiles(["C"] * N_ROADS, N_STEPS, DT, 20.0, rng=1)
    road_of = np.repeat(np.arange(N_ROADS), N_MASSES)
    m3 = np.random.default_rng(0).integers(50, 201, size=N_ROADS * N_MASSES).astype(float)
    L, TB = 32, 1000
    candidates = {"project kernel (physics/fused.py)": fused._kernel,
                  f"lane-parallel, {L} lanes, {TB}-step buffer": lane_kernel(L, TB),
                  "  its arithmetic only (final step written)": lane_kernel(L, TB, write_back=False)}
    few = slice(0, len(m3), 97)  # 104 recordings: also a partial last block
    for name, kernel in list(candidates.items())[1:2]:
        for measurement in ("consistent", "paper"):
            ref, got = (tuple(np.empty((len(m3[few]), N_STEPS)) for _ in range(4)) for _ in range(2))
            simulate(fused._kernel, roads, road_of[few], m3[few], ref, measurement)
            simulate(kernel, roads, road_of[few], m3[few], got, measurement)
            same = all(np.array_equal(a, b) for a, b in zip(ref, got))
            print(f"{name}, {measurement}: bit-identical to the project kernel in float64: {same}")
    for kernel in candidates.values():  # compile
        simulate(kernel, roads, road_of[:64], m3[:64], tuple(np.ones((64, N_STEPS), np.float32) for _ in range(4)))
    row_copy, lane_copy = copy_floor(L, TB, False), copy_floor(L, TB, True)
    floors = {"floor: parallel fill, no arithmetic": lambda o: fill(*o, 1.0),
              f"floor: copy from row-major block buffers ({L} x {TB})": lambda o: row_copy(*o),
              f"floor: copy from lane-major block buffers ({L} x {TB}, transposing)": lambda o: lane_copy(*o)}
    for f in floors.values():  # compile
        f(tuple(np.ones((64, N_STEPS), np.float32) for _ in range(4)))

    out = tuple(np.ones((len(m3), N_STEPS), np.float32) for _ in range(4))
    times = {name: [] for name in [*candidates, *floors]}
    for r in range(args.rounds):
        order = list(candidates.items())
        for name, kernel in (order if r % 2 == 0 else order[::-1]):
            times[name].append(simulate(kernel, roads, road_of, m3, out))
        for name, f in floors.items():
            t0 = time.perf_counter()
            f(out)
            times[name].append(time.perf_counter() - t0)
    print(f"paper size, {numba.get_num_threads()} threads, float32 output already touched; median of "
          f"{args.rounds} rounds:")
    for name, ts in times.items():
        print(f"  {name}: {np.median(ts):.3f} s ({' / '.join(f'{t:.3f}' for t in ts)})")


if __name__ == "__main__":
    main()
