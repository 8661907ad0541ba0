"""Recordings a user might bring, simulated without the package's simulator: the seat of the quarter car driven by
a body whose acceleration is a sum of sines (a road's motion seen through the car's body), solved by scipy's
solve_ivp. The seat equation z'' = -p1 (z' - y') - p2 (z - y) is integrated for the relative state from rest, so
the true p is known; the files are written in hybrid-sysid-predict's formats (docs/predict.md)."""

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

C3, K3 = 615.0, 98935.0  # the paper's seat damper and spring (sec. 2.2)
N_SINES = 40


def seat_recordings(n: int, n_steps: int, dt: float = 0.005, seed: int = 0):
    """n recordings (seat, body) (n, n_steps) in m/s^2 and their true p (n, 2), m3 (n,) uniform in [50, 200] kg.

    Each body acceleration is a sum of sines from 0.8 to 20 Hz with random phases and amplitudes; the recordings'
    levels span 30x (smooth to rough roads). The relative state x = z - y, v = z' - y' starts at rest and follows
    v' = -p1 v - p2 x - y''(t); the seat's acceleration is z'' = -p1 v - p2 x, sampled at t = k dt."""
    rng = np.random.default_rng(seed)
    m3 = rng.uniform(50.0, 200.0, n)
    p = np.stack([C3 / m3, K3 / m3], axis=1)
    freqs = 2 * np.pi * np.geomspace(0.8, 20.0, N_SINES)
    level = np.geomspace(0.1, 3.0, n)[rng.permutation(n)]  # m/s^2 per sine, before the roll-off
    amps = level[:, None] * rng.uniform(0.5, 1.5, (n, N_SINES)) / (1 + (freqs / (2 * np.pi * 8.0)) ** 2)
    phases = rng.uniform(0, 2 * np.pi, (n, N_SINES))

    def body(t):
        return np.sum(amps * np.sin(freqs * t + phases), axis=1)  # (n,)

    def rhs(t, y):
        x, v = y[:n], y[n:]
        return np.concatenate([v, -p[:, 0] * v - p[:, 1] * x - body(t)])

    t = dt * np.arange(n_steps)
    sol = solve_ivp(rhs, (0.0, t[-1]), np.zeros(2 * n), t_eval=t, method="DOP853", rtol=1e-10, atol=1e-12)
    assert sol.success, sol.message
    x, v = sol.y[:n], sol.y[n:]
    seat = -p[:, :1] * v - p[:, 1:] * x
    body_acc = np.stack([body(tk) for tk in t], axis=1)
    return seat, body_acc, p, m3


def write_folder(folder, seat, body, dt: float = 0.005, npz_from: int | None = None):
    """One CSV per recording (time, seat_acc, body_acc), named rec000.csv ...; with ``npz_from``, the recordings
    from that index on go into one .npz of 2-D arrays instead (named batch:0, batch:1, ...). Returns the names in
    the order of ``seat``."""
    folder.mkdir(parents=True, exist_ok=True)
    n = len(seat) if npz_from is None else npz_from
    names = []
    for i in range(n):
        frame = pd.DataFrame({"time": dt * np.arange(seat.shape[1]), "seat_acc": seat[i], "body_acc": body[i]})
        frame.to_csv(folder / f"rec{i:03d}.csv", index=False)
        names.append(f"rec{i:03d}")
    if npz_from is not None:
        np.savez(folder / "batch.npz", seat_acc=seat[npz_from:], body_acc=body[npz_from:], dt=dt)
        names += [f"batch:{i}" for i in range(len(seat) - npz_from)]
    return names


def write_labels(path, names, p, m3=None, form: str = "p"):
    """A labels CSV: recording, p1, p2 (form "p") or recording, c3, k3, m3 (form "c3k3m3")."""
    if form == "p":
        frame = pd.DataFrame({"recording": names, "p1": p[:, 0], "p2": p[:, 1]})
    else:
        frame = pd.DataFrame({"recording": names, "c3": p[:, 0] * m3, "k3": p[:, 1] * m3, "m3": m3})
    frame.to_csv(path, index=False)
    return path
