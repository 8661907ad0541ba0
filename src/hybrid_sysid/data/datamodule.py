"""LightningDataModule: random training windows, fixed seeded evaluation windows, Gaussian sensor noise."""

from __future__ import annotations

from typing import Iterator, Sequence

import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, IterableDataset

from hybrid_sysid.data.dataset import DatasetSpec, QCMDataset, get_dataset
from hybrid_sysid.data.splits import SPLITS, split_by_road
from hybrid_sysid.physics import relative_states


def _windows(arr: np.ndarray, window: int) -> np.ndarray:
    """A read-only view of every window of every recording: (recordings, starts, window), no copy."""
    return np.lib.stride_tricks.sliding_window_view(arr, window, axis=1)


def gather(windows: np.ndarray, rows: np.ndarray, starts: np.ndarray) -> torch.Tensor:
    """windows[rows[i], starts[i]] for every i: arr[rows[i], starts[i]:starts[i] + window], one contiguous copy.

    Indexing the window view copies whole rows; torch's advanced indexing with a (batch, window) column index
    takes over 10x as long (benchmarks/README.md, "Data pipeline").
    """
    return torch.from_numpy(windows[rows, starts])


class QCMData:
    """Window views of the dataset arrays plus the window / noise logic shared by training and evaluation."""

    def __init__(self, ds: QCMDataset, window: int):
        self.dt = ds.spec.dt
        self.measurement = ds.spec.measurement
        self.window = window
        self.seat, self.body = _windows(ds.seat_acc, window), _windows(ds.body_acc, window)
        self.rel_vel, self.rel_disp = _windows(ds.rel_vel, window), _windows(ds.rel_disp, window)
        self.params = torch.from_numpy(ds.params.astype(np.float32))
        self.n_steps = ds.seat_acc.shape[1]

    def batch(self, rows, starts, noise: np.ndarray | None = None) -> dict[str, torch.Tensor]:
        rows, starts = np.asarray(rows, dtype=np.int64), np.asarray(starts, dtype=np.int64)
        signals = torch.stack([gather(self.seat, rows, starts), gather(self.body, rows, starts)], dim=1)
        rel_vel, rel_disp = gather(self.rel_vel, rows, starts), gather(self.rel_disp, rows, starts)
        if noise is not None:  # what the noise adds to the relative states, re-integrated from the window's start
            nv, nd = relative_states(noise[:, 0], noise[:, 1], self.dt, self.measurement)
            signals = signals + torch.from_numpy(noise.astype(np.float32))
            rel_vel = rel_vel + torch.from_numpy(nv.astype(np.float32))
            rel_disp = rel_disp + torch.from_numpy(nd.astype(np.float32))
        index = torch.from_numpy(rows)
        return {"signals": signals, "params": self.params[index], "rel_vel": rel_vel, "rel_disp": rel_disp,
                "index": index}


class RandomWindows(IterableDataset):
    """An endless stream of training batches; trainer.max_steps ends training.

    Pass e visits every training recording once, in random order, each at a fresh random window start, from
    a generator seeded by (seed, e), so the stream is reproducible and ``resume_at`` can resume it exactly.
    Whole batches are cut with vectorised indexing. One stream (no epochs) also spares Lightning's per-epoch
    overhead, which would dominate on small datasets.

    ``rank`` (several devices, DDP) picks the stream: rank 0 draws the one-device stream, rank r > 0 its own,
    seeded by (seed, e, r), so N ranks see N different batches per step.
    """

    def __init__(self, data: QCMData, rows: np.ndarray, batch_size: int, seed: int, noise_std: float = 0.0,
                 rank: int = 0):
        self.data, self.rows, self.batch_size = data, rows, batch_size
        self.seed, self.noise_std, self.start_batch, self.rank = seed, noise_std, 0, rank

    def _key(self, *parts: int) -> list[int]:
        return [self.seed, *parts] + ([self.rank] if self.rank else [])

    @property
    def batches_per_pass(self) -> int:
        return -(-len(self.rows) // self.batch_size)

    def resume_at(self, batch: int) -> None:
        """Start the next iteration at this batch number, as if the batches before it had been drawn."""
        self.start_batch = int(batch)

    def passes(self, start_batch: int = 0) -> Iterator[dict[str, torch.Tensor]]:
        e, skip = divmod(start_batch, self.batches_per_pass)
        while True:
            yield from self.one_pass(e, skip)
            e, skip = e + 1, 0

    def one_pass(self, e: int, skip: int = 0) -> Iterator[dict[str, torch.Tensor]]:
        rng = np.random.default_rng(self._key(1000 + e))
        order = rng.permutation(self.rows)
        starts = rng.integers(0, self.data.n_steps - self.data.window + 1, size=len(order))
        for b in range(skip, self.batches_per_pass):
            sl = slice(b * self.batch_size, (b + 1) * self.batch_size)
            noise = None
            if self.noise_std > 0:  # one generator per batch, so a resumed stream draws the same noise
                noise_rng = np.random.default_rng(self._key(2000 + e, b))
                noise = self.noise_std * noise_rng.standard_normal((len(order[sl]), 2, self.data.window))
            yield self.data.batch(order[sl], starts[sl], noise)

    def __iter__(self) -> Iterator[dict[str, torch.Tensor]]:
        return self.passes(self.start_batch)


class QCMDataModule(L.LightningDataModule):
    """Simulated (or cached) quarter-car recordings cut into windows.

    Training: an endless stream of random windows (``RandomWindows``), optional noise ``train_std``; its
    position is the data module's state in a checkpoint, so a resumed run draws the batches an uninterrupted
    one would.
    Evaluation: one fixed, seeded window per recording (or K of them: ``eval_batch(windows=K)``); Gaussian
    noise of each std in ``eval_std`` added to both channels, from one seeded standard-normal draw per split
    scaled to each level (so levels differ only in size, which keeps robustness curves smooth).
    """

    def __init__(
        self,
        spec: DatasetSpec,
        cache_dir: str | None = None,
        window: int = 500,
        batch_size: int = 64,
        eval_batch_size: int = 1000,
        train_fraction: float = 0.8,
        val_fraction: float = 0.125,
        eval_std: Sequence[float] = (0.0, 0.01),
        train_std: float = 0.0,
        seed: int = 0,
    ):
        super().__init__()
        spec.validate()
        if window < 1 or window > spec.n_steps:
            raise ValueError(f"data.window = {window} is not allowed: must lie in [1, data.n_steps = {spec.n_steps}]")
        if batch_size < 1:
            raise ValueError(f"model.batch_size = {batch_size} is not allowed: must be >= 1")
        for s in list(eval_std) + [train_std]:
            if not s >= 0:
                raise ValueError(f"noise std {s} is not allowed: noise.eval_std and noise.train_std must be >= 0")
        self.split = split_by_road(spec.n_roads, spec.n_masses, train_fraction, val_fraction)
        self.spec, self.cache_dir, self.window = spec, cache_dir, window
        self.batch_size, self.eval_batch_size = batch_size, eval_batch_size
        self.eval_std, self.train_std, self.seed = [float(s) for s in eval_std], float(train_std), seed
        self.dataset: QCMDataset | None = None
        self.data: QCMData | None = None
        self.train_windows: RandomWindows | None = None
        self._eval_cache: dict = {}

    def prepare_data(self) -> None:
        get_dataset(self.spec, self.cache_dir)  # simulate and cache once

    def setup(self, stage: str | None = None) -> None:
        if self.data is None:
            self.dataset = get_dataset(self.spec, self.cache_dir)
            self.data = QCMData(self.dataset, self.window)
            self.train_windows = RandomWindows(self.data, self.split.train, self.batch_size, self.seed, self.train_std)

    def rows(self, split: str) -> np.ndarray:
        return getattr(self.split, split)

    def n_starts(self) -> int:
        """How many window starts a recording offers."""
        return self.spec.n_steps - self.window + 1

    def eval_batch(self, split: str, noise_std: float = 0.0, limit: int | None = None,
                   windows: int = 1) -> dict[str, torch.Tensor]:
        """All (or the first ``limit``) recordings of a split at their fixed windows, with noise of this std.

        ``windows`` = K fixed windows per recording, laid out recording by recording (batch row i * K + j is
        window j of recording i). Window 0 starts where the K = 1 window does; windows 1..K-1 come from separate
        seeded streams, one per j (so the K = 4 windows are the first four of the K = 8 ones), with starts
        distinct within a recording. With K > 1 each recording gets ONE noise realisation over its whole
        series and every window is cut from it, so overlapping windows share their noise as they would in a
        real recording; averaging K windows then gains only what one recording honestly offers. K = 1 draws
        noise for its window alone: statistically the same thing, without a series-long draw.
        """
        is_int = isinstance(windows, (int, np.integer)) and not isinstance(windows, bool)
        if not is_int or not 1 <= windows <= self.n_starts():
            raise ValueError(f"evaluation.windows = {windows!r} is not allowed: every K must be an integer in "
                             f"[1, data.n_steps - data.window + 1 = {self.n_starts()}]")
        key = (split, float(noise_std), limit, int(windows))
        if key in self._eval_cache:
            return self._eval_cache[key]
        self.setup()
        rows = self.rows(split)
        code = SPLITS.index(split)
        rng = np.random.default_rng([self.seed, code])
        starts = rng.integers(0, self.n_starts(), size=len(rows))
        base = rng.standard_normal((len(rows), 2, self.window)) if noise_std > 0 else None
        if windows > 1:
            starts, base = self._more_windows(rows, code, starts, base, windows)
        if limit is not None:
            rows, starts = rows[:limit], starts[:limit]
            base = None if base is None else base[:limit]
        if windows > 1:  # flatten to one batch row per window, recording-major
            rows, starts = np.repeat(rows, windows), starts.reshape(-1)
            base = None if base is None else base.reshape(-1, 2, self.window)
        batch = self.data.batch(rows, starts, None if base is None else noise_std * base)
        if windows == 1:  # K > 1 serves the final evaluation once; keep only K = 1 (curves reuse it)
            self._eval_cache[key] = batch
        return batch

    def _more_windows(self, rows, code, starts0, base0, k):
        """(n, K) starts and (n, K, 2, window) standard-normal noise cut from one series-long draw per
        recording; column 0 starts where the K = 1 window does."""
        n = len(rows)
        starts = np.empty((n, k), dtype=np.int64)
        starts[:, 0] = starts0
        for j in range(1, k):
            g = np.random.default_rng([self.seed, code, 100, j])
            s = g.integers(0, self.n_starts(), size=n)
            clash = (s[:, None] == starts[:, :j]).any(axis=1)
            while clash.any():  # redraw clashing starts only; ends as K <= the number of starts
                s[clash] = g.integers(0, self.n_starts(), size=int(clash.sum()))
                clash = (s[:, None] == starts[:, :j]).any(axis=1)
            starts[:, j] = s
        if base0 is None:
            return starts, None
        # float32 halves the memory of the series-long draw (2000 x 2 x 6000 on the paper's test split: 96 MB)
        series = np.random.default_rng([self.seed, code, 300]).standard_normal(
            (n, 2, self.spec.n_steps), dtype=np.float32)
        cols = starts[:, :, None] + np.arange(self.window)  # (n, K, window)
        base = np.stack([np.take_along_axis(series[:, c], cols.reshape(n, -1), axis=1) for c in (0, 1)], axis=1)
        return starts, base.reshape(n, 2, k, self.window).transpose(0, 2, 1, 3).astype(np.float64)

    def eval_dataloader(self, split: str, noise_std: float = 0.0, limit: int | None = None,
                        windows: int = 1) -> DataLoader:
        full = self.eval_batch(split, noise_std, limit, windows)
        n = len(full["index"])
        size = self.eval_batch_size
        chunks = [{k: v[i:i + size] for k, v in full.items()} for i in range(0, n, size)]
        return DataLoader(chunks, batch_size=None)

    def state_dict(self) -> dict:
        """Saved in checkpoints: how many training batches the run has taken, one per optimiser step
        (``accumulate_grad_batches`` with gradient accumulation)."""
        if self.trainer is None:
            return {}
        return {"train_batches": self.trainer.global_step * self.trainer.accumulate_grad_batches}

    def load_state_dict(self, state_dict: dict) -> None:
        """Restored from a checkpoint before training starts: the stream continues where the run left it."""
        if "train_batches" in state_dict:
            self.setup("fit")
            self.train_windows.resume_at(state_dict["train_batches"])

    def transfer_batch_to_device(self, batch, device, dataloader_idx):
        # batches are built on the CPU, and Lightning's default walks every batch to move it nowhere: ~0.1 ms
        # a step (benchmarks/README.md, "Training throughput")
        if device.type == "cpu":
            return batch
        return super().transfer_batch_to_device(batch, device, dataloader_idx)

    def train_dataloader(self) -> DataLoader:
        if self.trainer is not None:  # called inside each launched process, where the rank is known
            self.train_windows.rank = self.trainer.global_rank
        return DataLoader(self.train_windows, batch_size=None)

    def val_dataloader(self) -> DataLoader:
        return self.eval_dataloader("val", 0.0)

    def test_dataloader(self) -> list[DataLoader]:
        return [self.eval_dataloader("test", s) for s in self.eval_std]
