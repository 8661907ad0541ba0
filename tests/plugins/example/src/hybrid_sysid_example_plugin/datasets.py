"""A seat shaken by sines, its truth known: a data module, as a plugin.

Each recording's body moves as a sum of sines, y'' = sum_j a_j sin(w_j t + phi_j). Its seat, a mass m3 on the
car's C3 and K3, follows in steady state: the relative motion x = z - y obeys x'' + p1 x' + p2 x = -y'', with
p = (C3, K3) / m3, so each sine of y'' drives x as a_j H(w_j) sin(w_j t + phi_j + arg H), H(w) = -1 / (p2 - w^2 +
i w p1). The samples are exact, so the labels are the truth and the seat z'' = y'' + x'' = -p1 x' - p2 x holds at
every sample.
"""

from types import SimpleNamespace

import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, IterableDataset

SPLITS = ("train", "val", "test")


class SineSeatDataModule(L.LightningDataModule):
    def __init__(
        self,
        window: int,
        n_steps: int,
        dt: float,
        m3_min: float,
        m3_max: float,
        c3: float,
        k3: float,
        batch_size: int = 64,
        seed: int = 0,
        data_seed: int = 0,
        recordings: int = 48,
        sines: int = 3,
        band_hz: tuple = (0.5, 4.0),
        test_fraction: float = 0.25,
    ):
        super().__init__()
        if not 1 <= window <= n_steps:
            raise ValueError(f"window = {window} must lie in [1, n_steps = {n_steps}]")
        if recordings < 4 or sines < 1:
            raise ValueError(f"recordings = {recordings} must be >= 4 and sines = {sines} >= 1")
        self.window, self.n_steps, self.dt = int(window), int(n_steps), float(dt)
        self.m3_range, self.c3, self.k3 = (int(m3_min), int(m3_max)), float(c3), float(k3)
        self.batch_size, self.seed, self.recordings = int(batch_size), int(seed), int(recordings)
        self.data_seed = int(data_seed)  # the recordings' and the split's; seed: the windows'
        self.sines, self.band_hz, self.test_fraction = int(sines), tuple(band_hz), float(test_fraction)
        self.dataset = None  # the recordings, made in setup: the constructor loads nothing

    def setup(self, stage=None):
        if self.dataset is not None:
            return
        rng = np.random.default_rng(self.data_seed)
        n, t = self.recordings, np.arange(self.n_steps) * self.dt
        m3 = rng.integers(self.m3_range[0], self.m3_range[1] + 1, size=n).astype(float)
        p = np.stack([self.c3 / m3, self.k3 / m3], axis=1)
        w = 2 * np.pi * rng.uniform(*self.band_hz, size=(n, self.sines, 1))
        a = rng.uniform(0.5, 1.5, size=(n, self.sines, 1))  # m/s^2
        phase = rng.uniform(0, 2 * np.pi, size=(n, self.sines, 1)) + w * t
        h = -1.0 / (p[:, 1:, None] - w**2 + 1j * w * p[:, :1, None])  # x per unit y'', at each sine's frequency
        body = (a * np.sin(phase)).sum(axis=1)
        x = (a * np.imag(h * np.exp(1j * phase))).sum(axis=1)
        v = (a * np.imag(1j * w * h * np.exp(1j * phase))).sum(axis=1)
        seat = body + (a * np.imag(-(w**2) * h * np.exp(1j * phase))).sum(axis=1)
        order = rng.permutation(n)
        n_test = max(1, round(self.test_fraction * n))
        n_val = max(1, round(self.test_fraction * (n - n_test)))
        self.split = dict(zip(SPLITS, (order[n_test + n_val :], order[n_test : n_test + n_val], order[:n_test])))
        self.dataset = SimpleNamespace(
            spec=SimpleNamespace(dt=self.dt, measurement="continuous"),  # exact samples of the continuous motion
            seat_acc=seat.astype(np.float32),
            body_acc=body.astype(np.float32),
            rel_vel=v.astype(np.float32),
            rel_disp=x.astype(np.float32),
            params=p,
            m3=m3,
            road_class=np.full(n, "sine"),
        )

    def rows(self, split):
        self.setup()
        return self.split[split]

    def batch(self, rows, starts, noise_std=0.0, rng=None):
        """The windows of ``rows`` at ``starts``: signals with Gaussian noise of ``noise_std`` on both channels,
        the true p and the clean relative states (what the hybrid objectives read)."""
        cols = starts[:, None] + np.arange(self.window)
        d = self.dataset
        signals = np.stack([d.seat_acc[rows[:, None], cols], d.body_acc[rows[:, None], cols]], axis=1)
        if noise_std > 0:
            signals = signals + noise_std * rng.standard_normal(signals.shape)
        return {
            "signals": torch.from_numpy(signals.astype(np.float32)),
            "params": torch.from_numpy(d.params[rows]),
            "rel_vel": torch.from_numpy(d.rel_vel[rows[:, None], cols]),
            "rel_disp": torch.from_numpy(d.rel_disp[rows[:, None], cols]),
        }

    def eval_batch(self, split, noise_std=0.0, limit=None, windows=1):
        rows = self.rows(split)[:limit]
        starts_count = self.n_steps - self.window + 1
        if windows > starts_count:
            raise ValueError(f"windows = {windows}: a recording offers {starts_count} window starts")
        rng = np.random.default_rng([self.seed, SPLITS.index(split)])
        starts = np.stack([rng.choice(starts_count, size=windows, replace=False) for _ in rows])
        noise = np.random.default_rng([self.seed, SPLITS.index(split), 1])  # the same draw at every level
        return self.batch(np.repeat(rows, windows), starts.reshape(-1), noise_std, noise)

    def eval_dataloader(self, split, noise_std=0.0, limit=None, windows=1):
        return DataLoader([self.eval_batch(split, noise_std, limit, windows)], batch_size=None)

    def train_dataloader(self):
        return DataLoader(RandomWindows(self), batch_size=None)

    def val_dataloader(self):
        return self.eval_dataloader("val")


class RandomWindows(IterableDataset):
    """Training batches without end: random recordings of the training split at random starts, seeded."""

    def __init__(self, dm):
        self.dm = dm

    def __iter__(self):
        dm, rng = self.dm, np.random.default_rng([self.dm.seed, 7])
        train = dm.rows("train")
        while True:
            rows = rng.choice(train, size=dm.batch_size)
            yield dm.batch(rows, rng.integers(0, dm.n_steps - dm.window + 1, size=dm.batch_size))
