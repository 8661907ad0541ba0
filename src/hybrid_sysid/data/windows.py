"""Windows of the recordings: views without copies, sensor noise and its re-integration, the training stream.

``WindowCutter`` turns (recording, start) pairs into batches; ``RandomWindows`` is the endless, resumable stream of
training batches. The LightningDataModule around them is hybrid_sysid.data.datamodule.
"""

from __future__ import annotations

from typing import Iterator

import numpy as np
import torch
from torch.utils.data import IterableDataset

from hybrid_sysid.core.checks import check_choice
from hybrid_sysid.core.options import INTEGRATION_RULES
from hybrid_sysid.data.dataset import SimulatedDataset
from hybrid_sysid.data.outside import OutsideFit
from hybrid_sysid.data.spec import starts_offered
from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.filters import fir_valid


def _windows(arr: np.ndarray, window: int) -> np.ndarray:
    """A read-only view of every window of every recording: (recordings, starts, window), no copy."""
    return np.lib.stride_tricks.sliding_window_view(arr, window, axis=1)


def gather(windows: np.ndarray, rows: np.ndarray, starts: np.ndarray) -> torch.Tensor:
    """windows[rows[i], starts[i]] for every i: arr[rows[i], starts[i]:starts[i] + window], one contiguous copy.

    Indexing the window view copies whole rows; torch's advanced indexing with a (batch, window) column index
    takes many times as long (benchmarks/README.md, "Data pipeline").
    """
    return torch.from_numpy(windows[rows, starts])


# The rule each measurement's recordings are re-integrated by (physics.relative_states): noise integrated from
# t0 with the signals follows it, so the state it carries into a window does too.
RULES = {"paper": "symplectic", "consistent": "symplectic", "continuous": "trapezoid"}


def start_state(starts: np.ndarray, dt: float, normals: np.ndarray, rule: str = "symplectic") -> np.ndarray:
    """The part of the relative velocity and displacement that unit-variance white noise on both channels,
    integrated from t0 by ``rule``, has reached at each window start s and that the window's own noise does not
    enter: (B, 2) = (V, X). Exact draws from their joint Gaussian (one pair of standard normals ``normals``
    (B, 2) per window), so a batch needs no series-long noise draw. d_j = seat noise - body noise (variance 2).

    "symplectic" (v_k = v_{k-1} + dt a_{k-1}): V = dt sum_{j<s} d_j is rel_vel at s and X = dt^2 sum_{j<s}
    (s - 1 - j) d_j rel_disp at s - 1: Var V = 2 dt^2 s, Var X = 2 dt^4 sum m^2, Cov = 2 dt^3 sum m (m < s).
    The window continues them as v_{s+k} = V + lv_k, x_{s+k} = X + (k + 1) dt V + lx_k.

    "trapezoid" (v_k = v_{k-1} + dt (a_{k-1} + a_k) / 2, measurement "continuous"): rel_vel and rel_disp at s
    hold the window's first sample, v_s = V + dt d_s / 2 and x_s = X + dt^2 d_s / 4 (``WindowCutter.batch``
    adds those), with V = dt (d_0 / 2 + sum_{0<j<s} d_j) and X = dt^2 ((2s - 1) d_0 / 4 + sum_{0<j<s} (s - j)
    d_j): Var V = 2 dt^2 (s - 3/4), Cov = 2 dt^3 ((2s - 1) / 8 + s (s - 1) / 2), Var X = 2 dt^4 ((2s - 1)^2 /
    16 + (s - 1) s (2s - 1) / 6). The window continues them as v_{s+k} = v_s + lv_k, x_{s+k} = x_s + k dt v_s
    + lx_k. At s = 0 nothing came before: (0, 0) under both rules.
    lv, lx: the window's own noise integrated from zero by the same rule.
    """
    s = np.asarray(starts, dtype=np.float64)
    if rule == "symplectic":
        var_v = 2 * dt**2 * s
        cov = 2 * dt**3 * s * (s - 1) / 2
        var_x = 2 * dt**4 * (s - 1) * s * (2 * s - 1) / 6
    elif rule == "trapezoid":
        after = s > 0
        var_v = np.where(after, 2 * dt**2 * (s - 0.75), 0.0)
        cov = np.where(after, 2 * dt**3 * ((2 * s - 1) / 8 + s * (s - 1) / 2), 0.0)
        var_x = np.where(after, 2 * dt**4 * ((2 * s - 1) ** 2 / 16 + (s - 1) * s * (2 * s - 1) / 6), 0.0)
    else:
        check_choice("rule", rule, INTEGRATION_RULES)
    a = np.sqrt(var_v)
    b = np.divide(cov, a, out=np.zeros_like(a), where=a > 0)
    c = np.sqrt(np.maximum(var_x - b * b, 0.0))
    return np.stack([a * normals[:, 0], b * normals[:, 0] + c * normals[:, 1]], axis=1)


class WindowCutter:
    """Window views of the dataset arrays plus the window / noise logic shared by training and evaluation.

    integration "t0": the regressors are the states integrated from t0 over the whole recording, noise
    included: a window's noise adds its own re-integration plus the state the noise before it has reached
    (``start_state``), so no window starts from a noise-free state, as none does in a real recording.
    integration "window": each window is integrated from zero on its own, clean part and noise alike (a sensor
    stream cut anywhere, its states at the cut unknown): the regressors are then off by an unknown constant
    (rel_vel) and ramp (rel_disp), which a band-pass of zero DC and zero ramp gain removes.

    The noise follows the recording's integration rule (``RULES``; ``start_state``). Under measurement
    "continuous" the window's own noise is re-integrated with the trapezoid rule's gain correction, like the
    recording: a 3-tap filter that returns constants and ramps as they are, so in the window's interior the
    t0 noise is still its own integral plus a constant and a ramp. A series-long integration differs only at
    the window's edges (one sample at each end in rel_vel, two in rel_disp), which the correction leaves alone
    in the window but not in the series, and in the rel_disp constant, by dt^2 (d_s + d_{s+1} - d_0 - d_1) / 24
    (the series corrects sample s with d_{s-1}): O(dt) and O(dt^2) times the noise, far below its integral.

    ``fir`` (symmetric band-pass taps, or None): the batches also carry "seat_f", "rel_vel_f", "rel_disp_f",
    the three signals of the seat equation through that filter ('valid' part of the window, W - taps + 1
    samples). The clean part is filtered once per recording in float64 here; the noise part per batch by a
    torch FFT convolution in float32 (noise alone, without the offsets of the states before the window). Both
    integrations give the same filtered signals (the filter removes the offsets).

    ``outside_fir`` (the objective's, or None): ``outside`` is then the fit over each window's outside samples
    (hybrid_sysid.data.outside), whose "p_out" and "se_out" the training and evaluation batches carry;
    ``outside_target`` the fit (the objective's, one of data.outside.TARGETS; None: "ls"), ``outside_fix`` the
    recording fault's fix it takes.
    """

    def __init__(
        self,
        ds: SimulatedDataset,
        window: int,
        integration: str = "t0",
        fir: np.ndarray | None = None,
        outside_fir: np.ndarray | None = None,
        outside_target: str | None = None,
        outside_fix: str = "none",
    ):
        self.dt = ds.spec.dt
        self.measurement = ds.spec.measurement
        self.rule = RULES[self.measurement]
        self.window, self.integration = window, integration
        self.seat, self.body = _windows(ds.seat_acc, window), _windows(ds.body_acc, window)
        self.rel_vel, self.rel_disp = _windows(ds.rel_vel, window), _windows(ds.rel_disp, window)
        self.params = torch.from_numpy(ds.params.astype(np.float32))
        self.n_steps = ds.seat_acc.shape[1]
        # each recording's own length when they differ (a user's, zero-padded to the longest: data.recordings)
        self.lengths = getattr(ds, "lengths", None)
        self.outside = None
        if outside_fir is not None:
            self.outside = OutsideFit(
                ds.seat_acc,
                ds.body_acc,
                self.dt,
                self.measurement,
                window,
                outside_fir,
                outside_target,
                self.lengths,
                outside_fix,
            )
        self.fir = None
        if fir is not None:
            fir = np.asarray(fir, dtype=np.float64)
            # by FFT, far faster than torch's conv1d with 151 taps; a transform as long as the window
            # suffices, since the circular wrap-around only reaches the taps - 1 edge samples 'valid' drops
            self.nfft = 1 << int(np.ceil(np.log2(window)))
            self.fir = torch.fft.rfft(torch.from_numpy(fir.astype(np.float32)), self.nfft)
            self.taps = len(fir)
            short = window - len(fir) + 1
            self.filtered = [
                _windows(fir_valid(a, fir).astype(np.float32), short) for a in (ds.seat_acc, ds.rel_vel, ds.rel_disp)
            ]

    def starts_bound(self, rows: np.ndarray):
        """How many window starts each row's recording offers: one number for recordings of one length, else one
        per row (an upper bound for numpy's Generator.integers either way)."""
        steps = self.n_steps if self.lengths is None else self.lengths[np.asarray(rows, dtype=np.int64)]
        return starts_offered(steps, self.window)

    def batch(
        self, rows, starts, noise: np.ndarray | None = None, state: np.ndarray | None = None
    ) -> dict[str, torch.Tensor]:
        """Windows (rows[i], starts[i]); ``noise`` (B, 2, W) added to both channels; ``state`` (B, 2): the
        noise's (V, X) at each window's start by the recording's rule (``start_state``), used by integration
        "t0" (None: zero)."""
        rows, starts = np.asarray(rows, dtype=np.int64), np.asarray(starts, dtype=np.int64)
        signals = torch.stack([gather(self.seat, rows, starts), gather(self.body, rows, starts)], dim=1)
        if self.integration == "window":  # clean and noisy alike, from zero at the window's start
            acc = signals.numpy().astype(np.float64) + (0.0 if noise is None else noise)
            rel_vel, rel_disp = (
                torch.from_numpy(v.astype(np.float32))
                for v in relative_states(acc[:, 0], acc[:, 1], self.dt, self.measurement)
            )
        else:
            rel_vel, rel_disp = gather(self.rel_vel, rows, starts), gather(self.rel_disp, rows, starts)
        noise_f = None
        if noise is not None:
            nv, nd = relative_states(noise[:, 0], noise[:, 1], self.dt, self.measurement)
            if self.fir is not None:  # the window's own noise only: the filter removes what came before
                parts = torch.from_numpy(np.stack([noise[:, 0], nv, nd], axis=1).astype(np.float32))
                full = torch.fft.irfft(torch.fft.rfft(parts, self.nfft) * self.fir, self.nfft)
                noise_f = full[..., self.taps - 1 : self.window]
            if self.integration == "t0":
                if state is not None and self.rule == "symplectic":
                    # v_{s+k} = V + local v_k; x_{s+k} = X + (k + 1) dt V + local x_k
                    nv = nv + state[:, :1]
                    nd = nd + state[:, 1:] + self.dt * np.arange(1, self.window + 1) * state[:, :1]
                elif state is not None:  # trapezoid: the states at s hold the window's first sample
                    first = np.where(starts > 0, noise[:, 0, 0] - noise[:, 1, 0], 0.0)[:, None]
                    v_s = state[:, :1] + self.dt / 2 * first
                    x_s = state[:, 1:] + self.dt**2 / 4 * first
                    nv = nv + v_s
                    nd = nd + x_s + self.dt * np.arange(self.window) * v_s
                rel_vel = rel_vel + torch.from_numpy(nv.astype(np.float32))
                rel_disp = rel_disp + torch.from_numpy(nd.astype(np.float32))
            signals = signals + torch.from_numpy(noise.astype(np.float32))
        index = torch.from_numpy(rows)
        batch = {
            "signals": signals,
            "params": self.params[index],
            "rel_vel": rel_vel,
            "rel_disp": rel_disp,
            "index": index,
        }
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

    ``noise_std_max`` (None: every window at ``noise_std``): each window's std is log-uniform in [noise_std,
    noise_std_max], from a generator of its own per batch (key 4000 + e), so the windows' standard normals are
    those of a stream without it. With the data's ``outside`` fit, a batch also carries "p_out" and "se_out":
    fresh noise of each row's std over its whole recording, from another generator per batch (key 3000 + e).
    """

    def __init__(
        self,
        data: WindowCutter,
        rows: np.ndarray,
        batch_size: int,
        seed: int,
        noise_std: float = 0.0,
        rank: int = 0,
        noise_std_max: float | None = None,
    ):
        self.data, self.rows, self.batch_size = data, rows, batch_size
        self.seed, self.noise_std, self.start_batch, self.rank = seed, noise_std, 0, rank
        self.noise_std_max = noise_std_max

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

    def row_stds(self, e: int, b: int, n: int) -> np.ndarray:
        """The noise std of each of the n windows of batch b of pass e: log-uniform in [noise_std, noise_std_max]."""
        g = np.random.default_rng(self._key(4000 + e, b))
        return np.exp(g.uniform(np.log(self.noise_std), np.log(self.noise_std_max), size=n))

    def one_pass(self, e: int, skip: int = 0) -> Iterator[dict[str, torch.Tensor]]:
        rng = np.random.default_rng(self._key(1000 + e))
        order = rng.permutation(self.rows)
        starts = rng.integers(0, self.data.starts_bound(order), size=len(order))
        for b in range(skip, self.batches_per_pass):
            sl = slice(b * self.batch_size, (b + 1) * self.batch_size)
            noise = state = None
            std = self.noise_std
            if self.noise_std > 0:  # one generator per batch, so a resumed stream draws the same noise
                if self.noise_std_max is not None:
                    std = self.row_stds(e, b, len(order[sl]))
                std_w, std_s = (std, std) if np.isscalar(std) else (std[:, None, None], std[:, None])
                noise_rng = np.random.default_rng(self._key(2000 + e, b))
                noise = std_w * noise_rng.standard_normal((len(order[sl]), 2, self.data.window))
                state = std_s * start_state(
                    starts[sl], self.data.dt, noise_rng.standard_normal((len(order[sl]), 2)), self.data.rule
                )
            batch = self.data.batch(order[sl], starts[sl], noise, state)
            if self.data.outside is not None:
                normals = None
                if self.noise_std > 0:
                    g = np.random.default_rng(self._key(3000 + e, b))
                    normals = g.standard_normal((len(order[sl]), 2, self.data.n_steps))
                batch.update(self.data.outside.fit(order[sl], starts[sl], std, normals))
            yield batch

    def __iter__(self) -> Iterator[dict[str, torch.Tensor]]:
        return self.passes(self.start_batch)
