"""LightningDataModule: random training windows, fixed seeded evaluation windows, Gaussian sensor noise."""

from __future__ import annotations

import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader

from hybrid_sysid.data.cache import get_dataset
from hybrid_sysid.data.dataset import SimulatedDataset
from hybrid_sysid.data.outside import check_fix_fits
from hybrid_sysid.data.serving import Serving, takes_serving
from hybrid_sysid.data.spec import DatasetSpec, WindowSettings, check_eval_windows
from hybrid_sysid.data.splits import SPLITS
from hybrid_sysid.data.windows import RandomWindows, WindowCutter, start_state
from hybrid_sysid.physics import integrate


class QuarterCarDataModule(L.LightningDataModule):
    """Simulated (or cached) quarter-car recordings cut into windows.

    Training: an endless stream of random windows (``RandomWindows``), optional noise ``train_std``; its
    position is the data module's state in a checkpoint, so a resumed run draws the batches an uninterrupted
    one would.
    ``train_std_max`` (None: off): each training window's noise std log-uniform in [train_std, train_std_max].
    Validation windows carry noise of std ``train_std``, or the range's geometric mean (none when training is clean).
    Evaluation: one fixed, seeded window per recording (or K of them: ``eval_batch(windows=K)``); Gaussian
    noise of the std asked for (the config's noise.eval_std, through hybrid_sysid.training.evaluation) added to
    both channels, from one seeded standard-normal draw per split scaled to each level (so levels differ only in
    size, which keeps robustness curves smooth).

    ``fir``: the objective's band-pass taps (``objective.fir``), so the batches carry the filtered signals the
    objective reads; None for an objective without a filter. ``outside_fir``: the objective's band-pass of the fit
    over each window's outside samples (hybrid_sysid.data.outside), whose "p_out" and "se_out" the training and
    evaluation batches then carry; ``outside_target`` that fit, "eiv" or "ls" (the objective's; None: "ls").
    """

    @takes_serving
    def __init__(
        self,
        spec: DatasetSpec,
        cache_dir: str | None = None,
        *,
        train_fraction: float = WindowSettings.train_fraction,
        val_fraction: float = WindowSettings.val_fraction,
        **serving,
    ):
        """``serving``: Serving's keyword arguments (window, batch_size, eval_batch_size, train_std, seed,
        integration, fir, train_std_max, outside_fir, outside_target, outside_fix)."""
        super().__init__()
        served = Serving(**serving)
        spec.validate()
        self.settings = WindowSettings(served.window, served.integration, train_fraction, val_fraction)
        taps, outside_taps = (None if f is None else len(f) for f in (served.fir, served.outside_fir))
        self.settings.validate(spec, taps=taps, outside_taps=outside_taps)
        if outside_taps is not None:
            fit = served.outside_fix, served.outside_target
            check_fix_fits(*fit, spec.n_steps, served.window, outside_taps, spec.dt, spec.measurement)
        self._serve(served)
        self.split = self.settings.split(spec)
        self.spec, self.cache_dir = spec, cache_dir
        self.dataset: SimulatedDataset | None = None

    def _serve(self, served: Serving) -> None:
        """Checks ``served``'s batches and keeps its values as the attributes the run and the windows read."""
        self.batch_settings = served.batches
        self.batch_settings.validate()
        self.window, self.batch_size, self.eval_batch_size = served.window, served.batch_size, served.eval_batch_size
        self.train_std, self.seed, self.integration = float(served.train_std), served.seed, served.integration
        self.train_std_max = None if served.train_std_max is None else float(served.train_std_max)
        self.fir, self.outside_fir, self.outside_target = served.fir, served.outside_fir, served.outside_target
        self.outside_fix = served.outside_fix
        self.data: WindowCutter | None = None
        self.train_windows: RandomWindows | None = None
        self._eval_cache: dict = {}

    def prepare_data(self) -> None:
        # simulate and cache once; kept, so setup (before fit or after it) does not read the cache again
        if self.dataset is None:
            self.dataset = self._get_dataset()

    def setup(self, stage: str | None = None) -> None:
        if self.data is None:
            self.data = self._training_cutter()
            std, std_max = self.train_std, self.train_std_max
            self.train_windows = RandomWindows(
                self.data, self.rows("train"), self.batch_size, self.seed, std, noise_std_max=std_max
            )

    def _training_cutter(self) -> WindowCutter:
        if self.dataset is None:  # a DDP rank other than 0 (prepare_data ran elsewhere), or no fit
            self.dataset = self._get_dataset()
        return self._cut(self.dataset)

    def _cut(self, dataset) -> WindowCutter:
        return WindowCutter(
            dataset, self.window, self.integration, self.fir, self.outside_fir, self.outside_target, self.outside_fix
        )

    def _get_dataset(self) -> SimulatedDataset:
        # simulating runs numba's parallel kernel, whose OpenMP runtime torch shares: it leaves torch at numba's
        # thread count (all cores). Put back the run's own, which its numbers depend on
        # (docs/reliability/reproducibility.md)
        threads = torch.get_num_threads()
        try:
            return get_dataset(self.spec, self.cache_dir)
        finally:
            torch.set_num_threads(threads)

    def rows(self, split: str) -> np.ndarray:
        return getattr(self.split, split)

    def n_starts(self) -> int:
        """How many window starts a recording offers."""
        return self.settings.n_starts(self.spec)

    def cutter(self, split: str) -> WindowCutter:
        """The windows of a split's recordings: here one cutter over the whole dataset; a module that holds one
        split at a time (data.recordings) gives that split's."""
        self.setup()
        return self.data

    def eval_batch(
        self, split: str, noise_std: float = 0.0, limit: int | None = None, windows: int = 1
    ) -> dict[str, torch.Tensor]:
        """All (or the first ``limit``) recordings of a split at their fixed windows, with noise of this std.

        ``windows`` = K fixed windows per recording, laid out recording by recording (batch row i * K + j is
        window j of recording i). Window 0 starts where the K = 1 window does; windows 1..K-1 come from separate
        seeded streams, one per j (so the K = 4 windows are the first four of the K = 8 ones), with starts
        distinct within a recording. With K > 1 each recording gets ONE noise realisation over its whole
        series and every window is cut from it, so overlapping windows share their noise as they would in a
        real recording; averaging K windows then gains only what one recording honestly offers, and each window's
        integrated noise starts from the state that series has reached. K = 1 draws noise for its window alone
        and that state from its exact Gaussian (``start_state``): statistically the same thing, without a
        series-long draw. With the data's ``outside`` fit, its noise is one more seeded draw per recording over
        the whole recording (key 3000; every window of a recording fits with it), scaled to each level.
        """
        check_eval_windows([int(windows) if isinstance(windows, np.integer) else windows], self.n_starts())
        key = (split, float(noise_std), limit, int(windows))
        if key in self._eval_cache:
            return self._eval_cache[key]
        data = self.cutter(split)
        rows = self.rows(split)
        code = SPLITS.index(split)
        rng = np.random.default_rng([self.seed, code])
        starts = rng.integers(0, data.starts_bound(rows), size=len(rows))
        base = rng.standard_normal((len(rows), 2, self.window)) if noise_std > 0 else None
        # drawn after the window's noise, so that noise is the same whatever the integration
        state = None if base is None else start_state(starts, data.dt, rng.standard_normal((len(rows), 2)), data.rule)
        if windows > 1:
            starts, base, state = self._more_windows(data, rows, code, starts, base, windows)
        if limit is not None:
            rows, starts = rows[:limit], starts[:limit]
            base = None if base is None else base[:limit]
            state = None if state is None else state[:limit]
        if windows > 1:  # flatten to one batch row per window, recording-major
            rows, starts = np.repeat(rows, windows), starts.reshape(-1)
            base = None if base is None else base.reshape(-1, 2, self.window)
            state = None if state is None else state.reshape(-1, 2)
        if base is None:
            batch = data.batch(rows, starts)
        else:
            batch = data.batch(rows, starts, noise_std * base, noise_std * state)
        if data.outside is not None:
            normals = None
            if noise_std > 0:  # the first rows of the split's draw: a limited batch is a prefix of the full one
                n = len(rows) // windows
                g = np.random.default_rng([self.seed, code, 3000])
                normals = np.repeat(g.standard_normal((n, 2, self.spec.n_steps), dtype=np.float32), windows, axis=0)
            batch.update(data.outside.fit(rows, starts, noise_std, normals))
        if windows == 1:  # K > 1 serves the final evaluation once; keep only K = 1 (curves reuse it)
            self._eval_cache[key] = batch
        return batch

    def _more_windows(self, data, rows, code, starts0, base0, k):
        """(n, K) starts, (n, K, 2, window) standard-normal noise cut from one series-long draw per recording
        and (n, K, 2) the state that noise, integrated from t0 by the recording's rule, has reached at each start
        (``start_state``'s (V, X), by its convention for that rule); column 0 starts where the K = 1 window does."""
        n, high = len(rows), data.starts_bound(rows)
        starts = np.empty((n, k), dtype=np.int64)
        starts[:, 0] = starts0
        for j in range(1, k):
            g = np.random.default_rng([self.seed, code, 100, j])
            s = g.integers(0, high, size=n)
            clash = (s[:, None] == starts[:, :j]).any(axis=1)
            while clash.any():  # redraw clashing starts only; ends as K <= the number of starts
                s[clash] = g.integers(0, high if np.isscalar(high) else high[clash], size=int(clash.sum()))
                clash = (s[:, None] == starts[:, :j]).any(axis=1)
            starts[:, j] = s
        if base0 is None:
            return starts, None, None
        # float32 halves the memory of the series-long draw (2000 x 2 x 6000 on the paper's test split: 96 MB)
        series = np.random.default_rng([self.seed, code, 300]).standard_normal(
            (n, 2, self.spec.n_steps), dtype=np.float32
        )
        cols = starts[:, :, None] + np.arange(self.window)  # (n, K, window)
        base = np.stack([np.take_along_axis(series[:, c], cols.reshape(n, -1), axis=1) for c in (0, 1)], axis=1)
        diff = series[:, 0].astype(np.float64) - series[:, 1]
        vel, pos = integrate(diff, data.dt)
        if data.rule == "symplectic":
            before = np.maximum(starts - 1, 0)
            state = np.stack(
                [
                    np.take_along_axis(vel, starts, axis=1),
                    np.where(starts > 0, np.take_along_axis(pos, before, axis=1), 0.0),
                ],
                axis=-1,
            )
        else:
            # the trapezoid rule's (V, X) are symplectic Euler's sums at s, dt sum_{j<s} d_j and dt^2 sum_{j<s}
            # (s - j) d_j, with the first sample d_0 weighted dt / 2 and dt^2 (2s - 1) / 4 instead
            dt, first = data.dt, diff[:, :1]
            v = np.take_along_axis(vel, starts, axis=1) - dt / 2 * first
            x = np.take_along_axis(pos, starts, axis=1) - dt**2 * (2 * starts + 1) / 4 * first
            state = np.where((starts > 0)[..., None], np.stack([v, x], axis=-1), 0.0)
        return starts, base.reshape(n, 2, k, self.window).transpose(0, 2, 1, 3).astype(np.float64), state

    def eval_dataloader(
        self, split: str, noise_std: float = 0.0, limit: int | None = None, windows: int = 1
    ) -> DataLoader:
        full = self.eval_batch(split, noise_std, limit, windows)
        n = len(full["index"])
        # 256 windows a batch by default: a fast_cnn forward takes less per window than at 1000 (its activations
        # stay in the cache: benchmarks/README.md), and every network here treats windows one by one: the same numbers
        size = self.eval_batch_size
        chunks = [{k: v[i : i + size] for k, v in full.items()} for i in range(0, n, size)]
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
        # batches are built on the CPU, and Lightning's default walks every batch to move it nowhere: time in every
        # step (benchmarks/README.md, "Training throughput")
        if device.type == "cpu":
            return batch
        return super().transfer_batch_to_device(batch, device, dataloader_idx)

    def train_dataloader(self) -> DataLoader:
        if self.trainer is not None:  # called inside each launched process, where the rank is known
            self.train_windows.rank = self.trainer.global_rank
        return DataLoader(self.train_windows, batch_size=None)

    def val_dataloader(self) -> DataLoader:
        # with training noise, validation windows carry it too: label-free model selection (val/loss) then
        # judges what training optimises, noise included (a range's geometric mean, its middle in log std)
        return self.eval_dataloader("val", self.batch_settings.val_std)
