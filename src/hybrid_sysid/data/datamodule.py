"""LightningDataModule: random training windows, fixed seeded evaluation windows, Gaussian sensor noise."""

from __future__ import annotations

from typing import Iterator, Sequence

import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, IterableDataset

from hybrid_sysid.data.dataset import INTEGRATIONS, DatasetSpec, QCMDataset, get_dataset
from hybrid_sysid.data.splits import SPLITS, split_by_road
from hybrid_sysid.physics import integrate, relative_states
from hybrid_sysid.physics.filters import fir_valid


def _windows(arr: np.ndarray, window: int) -> np.ndarray:
    """A read-only view of every window of every recording: (recordings, starts, window), no copy."""
    return np.lib.stride_tricks.sliding_window_view(arr, window, axis=1)


def gather(windows: np.ndarray, rows: np.ndarray, starts: np.ndarray) -> torch.Tensor:
    """windows[rows[i], starts[i]] for every i: arr[rows[i], starts[i]:starts[i] + window], one contiguous copy.

    Indexing the window view copies whole rows; torch's advanced indexing with a (batch, window) column index
    takes over 10x as long (benchmarks/README.md, "Data pipeline").
    """
    return torch.from_numpy(windows[rows, starts])


def start_state(starts: np.ndarray, dt: float, normals: np.ndarray) -> np.ndarray:
    """The relative velocity and displacement that unit-variance white noise on both channels, integrated from
    t0, has reached at each window start: (B, 2) = (V, X), V = rel_vel before the window's first step, X =
    rel_disp one step before the window. Exact draws from their joint Gaussian (one pair of standard normals
    ``normals`` (B, 2) per window), so a batch needs no series-long noise draw.

    With d_j = seat noise - body noise (variance 2), symplectic Euler gives V = dt sum_{j<s} d_j and
    X = dt^2 sum_{j<s} (s - 1 - j) d_j: Var V = 2 dt^2 s, Var X = 2 dt^4 sum m^2, Cov = 2 dt^3 sum m (m < s).
    """
    s = np.asarray(starts, dtype=np.float64)
    var_v = 2 * dt ** 2 * s
    cov = 2 * dt ** 3 * s * (s - 1) / 2
    var_x = 2 * dt ** 4 * (s - 1) * s * (2 * s - 1) / 6
    a = np.sqrt(var_v)
    b = np.divide(cov, a, out=np.zeros_like(a), where=a > 0)
    c = np.sqrt(np.maximum(var_x - b * b, 0.0))
    return np.stack([a * normals[:, 0], b * normals[:, 0] + c * normals[:, 1]], axis=1)


class QCMData:
    """Window views of the dataset arrays plus the window / noise logic shared by training and evaluation.

    integration "t0": the regressors are the states integrated from t0 over the whole recording, noise
    included: a window's noise adds its own re-integration plus the state the noise before it has reached
    (``start_state``), so no window starts from a noise-free state, as none does in a real recording.
    integration "window": each window is integrated from zero on its own, clean part and noise alike (a sensor
    stream cut anywhere, its states at the cut unknown): the regressors are then off by an unknown constant
    (rel_vel) and ramp (rel_disp), which a band-pass of zero DC and zero ramp gain removes.

    ``fir`` (symmetric band-pass taps, or None): the batches also carry "seat_f", "rel_vel_f", "rel_disp_f",
    the three signals of the seat equation through that filter ('valid' part of the window, W - taps + 1
    samples). The clean part is filtered once per recording in float64 here; the noise part per batch by a
    torch FFT convolution in float32 (noise alone, without the offsets of the states before the window). Both
    integrations give the same filtered signals (the filter removes the offsets).
    """

    def __init__(self, ds: QCMDataset, window: int, integration: str = "t0", fir: np.ndarray | None = None):
        if integration not in INTEGRATIONS:
            raise ValueError(f"data.integration = {integration!r} is not allowed: one of {', '.join(INTEGRATIONS)}")
        self.dt = ds.spec.dt
        self.measurement = ds.spec.measurement
        self.window, self.integration = window, integration
        self.seat, self.body = _windows(ds.seat_acc, window), _windows(ds.body_acc, window)
        self.rel_vel, self.rel_disp = _windows(ds.rel_vel, window), _windows(ds.rel_disp, window)
        self.params = torch.from_numpy(ds.params.astype(np.float32))
        self.n_steps = ds.seat_acc.shape[1]
        self.fir = None
        if fir is not None:
            fir = np.asarray(fir, dtype=np.float64)
            if len(fir) > window:
                raise ValueError(f"objective.filter.taps = {len(fir)} is not allowed: "
                                 f"must be <= data.window = {window}")
            # by FFT, about 10x faster than torch's conv1d with 151 taps; a transform as long as the window
            # suffices, since the circular wrap-around only reaches the taps - 1 edge samples 'valid' drops
            self.nfft = 1 << int(np.ceil(np.log2(window)))
            self.fir = torch.fft.rfft(torch.from_numpy(fir.astype(np.float32)), self.nfft)
            self.taps = len(fir)
            short = window - len(fir) + 1
            self.filtered = [_windows(fir_valid(a, fir).astype(np.float32), short)
                             for a in (ds.seat_acc, ds.rel_vel, ds.rel_disp)]

    def batch(self, rows, starts, noise: np.ndarray | None = None,
              state: np.ndarray | None = None) -> dict[str, torch.Tensor]:
        """Windows (rows[i], starts[i]); ``noise`` (B, 2, W) added to both channels; ``state`` (B, 2): the
        noise's (V, X) at each window's start (``start_state``), used by integration "t0" (None: zero)."""
        rows, starts = np.asarray(rows, dtype=np.int64), np.asarray(starts, dtype=np.int64)
        signals = torch.stack([gather(self.seat, rows, starts), gather(self.body, rows, starts)], dim=1)
        if self.integration == "window":  # clean and noisy alike, from zero at the window's start
            acc = signals.numpy().astype(np.float64) + (0.0 if noise is None else noise)
            rel_vel, rel_disp = (torch.from_numpy(v.astype(np.float32))
                                 for v in relative_states(acc[:, 0], acc[:, 1], self.dt, self.measurement))
        else:
            rel_vel, rel_disp = gather(self.rel_vel, rows, starts), gather(self.rel_disp, rows, starts)
        noise_f = None
        if noise is not None:
            nv, nd = relative_states(noise[:, 0], noise[:, 1], self.dt, self.measurement)
            if self.fir is not None:  # the window's own noise only: the filter removes what came before
                parts = torch.from_numpy(np.stack([noise[:, 0], nv, nd], axis=1).astype(np.float32))
                full = torch.fft.irfft(torch.fft.rfft(parts, self.nfft) * self.fir, self.nfft)
                noise_f = full[..., self.taps - 1:self.window]
            if self.integration == "t0":
                if state is not None:  # v_{s+k} = V + local v_k; x_{s+k} = X + (k + 1) dt V + local x_k
                    nv = nv + state[:, :1]
                    nd = nd + state[:, 1:] + self.dt * np.arange(1, self.window + 1) * state[:, :1]
                rel_vel = rel_vel + torch.from_numpy(nv.astype(np.float32))
                rel_disp = rel_disp + torch.from_numpy(nd.astype(np.float32))
            signals = signals + torch.from_numpy(noise.astype(np.float32))
        index = torch.from_numpy(rows)
        batch = {"signals": signals, "params": self.params[index], "rel_vel": rel_vel, "rel_disp": rel_disp,
                 "index": index}
        if self.fir is not None:
            for i, key in enumerate(("seat_f", "rel_vel_f", "rel_disp_f")):
                batch[key] = gather(self.filtered[i], rows, starts)
                if noise_f is not None:
                    batch[key] = batch[key] + noise_f[:, i]
        return batch


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
            noise = state = None
            if self.noise_std > 0:  # one generator per batch, so a resumed stream draws the same noise
                noise_rng = np.random.default_rng(self._key(2000 + e, b))
                noise = self.noise_std * noise_rng.standard_normal((len(order[sl]), 2, self.data.window))
                state = self.noise_std * start_state(starts[sl], self.data.dt,
                                                     noise_rng.standard_normal((len(order[sl]), 2)))
            yield self.data.batch(order[sl], starts[sl], noise, state)

    def __iter__(self) -> Iterator[dict[str, torch.Tensor]]:
        return self.passes(self.start_batch)


class QCMDataModule(L.LightningDataModule):
    """Simulated (or cached) quarter-car recordings cut into windows.

    Training: an endless stream of random windows (``RandomWindows``), optional noise ``train_std``; its
    position is the data module's state in a checkpoint, so a resumed run draws the batches an uninterrupted
    one would.
    Validation windows carry noise of std ``train_std`` (none when training is clean).
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
        integration: str = "t0",
        fir: np.ndarray | None = None,
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
        if integration not in INTEGRATIONS:
            raise ValueError(f"data.integration = {integration!r} is not allowed: one of {', '.join(INTEGRATIONS)}")
        self.integration, self.fir = integration, fir
        self.dataset: QCMDataset | None = None
        self.data: QCMData | None = None
        self.train_windows: RandomWindows | None = None
        self._eval_cache: dict = {}

    def prepare_data(self) -> None:
        self._get_dataset()  # simulate and cache once

    def setup(self, stage: str | None = None) -> None:
        if self.data is None:
            self.dataset = self._get_dataset()
            self.data = QCMData(self.dataset, self.window, self.integration, self.fir)
            self.train_windows = RandomWindows(self.data, self.split.train, self.batch_size, self.seed, self.train_std)

    def _get_dataset(self) -> QCMDataset:
        # simulating runs numba's parallel kernel, whose OpenMP runtime torch shares: it leaves torch at numba's
        # thread count (all cores). Put back the run's own, which its numbers depend on (docs/reliability.md)
        threads = torch.get_num_threads()
        try:
            return get_dataset(self.spec, self.cache_dir)
        finally:
            torch.set_num_threads(threads)

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
        real recording; averaging K windows then gains only what one recording honestly offers, and each window's
        integrated noise starts from the state that series has reached. K = 1 draws noise for its window alone
        and that state from its exact Gaussian (``start_state``): statistically the same thing, without a
        series-long draw.
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
        # drawn after the window's noise, so that noise is the same whatever the integration
        state = None if base is None else start_state(starts, self.data.dt, rng.standard_normal((len(rows), 2)))
        if windows > 1:
            starts, base, state = self._more_windows(rows, code, starts, base, windows)
        if limit is not None:
            rows, starts = rows[:limit], starts[:limit]
            base = None if base is None else base[:limit]
            state = None if state is None else state[:limit]
        if windows > 1:  # flatten to one batch row per window, recording-major
            rows, starts = np.repeat(rows, windows), starts.reshape(-1)
            base = None if base is None else base.reshape(-1, 2, self.window)
            state = None if state is None else state.reshape(-1, 2)
        if base is None:
            batch = self.data.batch(rows, starts)
        else:
            batch = self.data.batch(rows, starts, noise_std * base, noise_std * state)
        if windows == 1:  # K > 1 serves the final evaluation once; keep only K = 1 (curves reuse it)
            self._eval_cache[key] = batch
        return batch

    def _more_windows(self, rows, code, starts0, base0, k):
        """(n, K) starts, (n, K, 2, window) standard-normal noise cut from one series-long draw per recording
        and (n, K, 2) the state that noise, integrated from t0, has reached at each start (``start_state``'s
        (V, X)); column 0 starts where the K = 1 window does."""
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
            return starts, None, None
        # float32 halves the memory of the series-long draw (2000 x 2 x 6000 on the paper's test split: 96 MB)
        series = np.random.default_rng([self.seed, code, 300]).standard_normal(
            (n, 2, self.spec.n_steps), dtype=np.float32)
        cols = starts[:, :, None] + np.arange(self.window)  # (n, K, window)
        base = np.stack([np.take_along_axis(series[:, c], cols.reshape(n, -1), axis=1) for c in (0, 1)], axis=1)
        vel, pos = integrate(series[:, 0].astype(np.float64) - series[:, 1], self.data.dt)
        before = np.maximum(starts - 1, 0)
        state = np.stack([np.take_along_axis(vel, starts, axis=1),
                          np.where(starts > 0, np.take_along_axis(pos, before, axis=1), 0.0)], axis=-1)
        return starts, base.reshape(n, 2, k, self.window).transpose(0, 2, 1, 3).astype(np.float64), state

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
        # with training noise, validation windows carry it too: label-free model selection (val/loss) then
        # judges what training optimises, noise included
        return self.eval_dataloader("val", self.train_std)

    def test_dataloader(self) -> list[DataLoader]:
        return [self.eval_dataloader("test", s) for s in self.eval_std]
