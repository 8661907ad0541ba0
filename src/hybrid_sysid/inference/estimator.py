"""A trained run as a tool: estimate p1 = C3 / m3, p2 = K3 / m3 and the seat mass m3 of recordings.

``Estimator.predict(seat_acc, body_acc, dt)`` cuts K evenly spaced windows from each recording, gives them to the
run's network exactly as training did (float32, shaped (batch, 2, data.window), channel 0 seat, channel 1 body;
eval mode, no gradients) and averages the K estimates; a least-squares baseline run estimates with its fit
(model.base.Baseline.estimate). Each row carries flags (inference.flags) that say when not to trust it, with one
warning per kind. ``load_estimator`` (inference.loading) makes one of a run directory; the command
``hybrid-sysid-predict`` (hybrid_sysid.cli.predict) only reads files and prints, calling this same code.
"""

from __future__ import annotations

import warnings
from fractions import Fraction
from typing import Sequence

import numpy as np
import pandas as pd
import torch
from omegaconf import DictConfig
from scipy.signal import resample_poly

from hybrid_sysid.core.checks import ConfigError, Shown, check_dt
from hybrid_sysid.core.options import DEFAULT_MEASUREMENT
from hybrid_sysid.data.readers import DT_RTOL
from hybrid_sysid.data.spec import window_starts
from hybrid_sysid.inference import flags as F
from hybrid_sysid.inference.inputs import (
    EstimateWarning,
    InputError,
    check_estimates,
    check_values,
    check_windows,
    recordings,
)
from hybrid_sysid.inference.memory import CHUNK, check_window_memory
from hybrid_sysid.model.base import Baseline
from hybrid_sysid.physics import QuarterCar

# The resampling ratio is a fraction with a denominator up to MAX_DENOMINATOR; the rate it gives may miss the
# run's rate by RATIO_RTOL. A time scale off by e scales p1 by (1 + e) and p2 by (1 + e)^2: 1e-4 is far below
# what any trained estimator resolves.
MAX_DENOMINATOR = 1000
RATIO_RTOL = 1e-4
COLUMNS = ["recording", "steps", "windows", "p1", "p1_std", "p2", "p2_std", "m3_from_p1", "m3_from_p2", "flag"]


class Estimator:
    """A run's network (or least-squares baseline) and what it needs to read a recording: the run's dt, window,
    car and measurement, its trained range and its own test error (``record``, its metrics.json)."""

    def __init__(
        self,
        net: torch.nn.Module | None,
        config: DictConfig,
        baseline: Baseline | None = None,
        record: dict | None = None,
    ):
        if (net is None) == (baseline is None):
            raise InputError("net", allowed="a network or a baseline, one of them")
        self.net = net
        self.baseline = baseline
        self.config = config
        self.record = record
        self.dt = float(config.data.dt)
        self.window = int(config.data.window)
        self.car = QuarterCar(**config.get("car", {}))
        self.measurement = str(config.data.get("measurement", DEFAULT_MEASUREMENT))
        self.trained = F.trained_range(config, net)
        self._reference: F.ChannelReference | None = None

    @property
    def reference(self) -> F.ChannelReference:
        """The channel features of recordings simulated from the run's data spec (computed once, on first use)."""
        if self._reference is None:
            band = F.resonance_band(self.trained.p_min[1], self.trained.p_max[1])
            try:
                self._reference = F.ChannelReference(self.config, self.window, band)
            except ConfigError as exc:  # a data spec the simulator refuses (a damaged or hand-edited config)
                raise InputError(
                    "run", allowed=f"a data spec that can be simulated for the channel check ({exc})"
                ) from None
        return self._reference

    def predict(
        self, seat_acc, body_acc, dt: float, windows: int = 8, resample: bool = False, names: Sequence | None = None
    ) -> pd.DataFrame:
        """Estimates per recording: p1, p2 averaged over ``windows`` windows, their std, and m3 from each.

        Parameters
        ----------
        seat_acc, body_acc : array_like or list of array_like
            Seat z'' and body y'' in m/s^2: 1-D (one recording), 2-D (recordings, steps), or a list of 1-D
            arrays (recordings of different lengths).
        dt : float
            Their sampling interval in s. It must equal the run's ``data.dt`` unless ``resample``.
        windows : int
            K >= 1, the windows averaged per recording; their starts are evenly spaced, first at 0, last at the end.
        resample : bool
            True: scipy's polyphase filter brings the recordings to the run's rate.
        names : sequence, optional
            One label per recording (default 0, 1, ...).

        Returns
        -------
        pandas.DataFrame
            One row per recording: ``recording``, ``steps``, ``windows``, ``p1``, ``p2`` (1/s, 1/s^2),
            ``p1_std``, ``p2_std``, ``m3_from_p1``, ``m3_from_p2`` (kg, m3 = C3 / p1 and K3 / p2 for the run's car)
            and ``flag`` (range, channels, run_error; empty when none). Each kind of flag also raises one
            ``EstimateWarning`` and is listed in ``table.attrs["warnings"]`` (docs/predict.md, "Flags").

        Raises
        ------
        InputError
            A ``ValueError`` naming the bad input: a short recording, a non-finite or out-of-float32 value, another
            ``dt``, bad ``windows`` or ``resample``, disagreeing shapes, or windows beyond the memory available.
        """
        check_windows(windows)
        if not isinstance(resample, (bool, np.bool_)):  # resample="false" is a true value: it would resample
            raise InputError("resample", resample, "True or False")
        pairs = recordings(seat_acc, body_acc)
        names = list(range(len(pairs))) if names is None else list(names)
        if len(names) != len(pairs):
            raise InputError("names", Shown(f"{len(names)} items"), f"one name for each of the {len(pairs)} recordings")
        dt = self._check_dt(dt, resample)
        k, resampled = int(windows), dt != self.dt
        stacked = []  # every check passes before any window is cut
        for name, (seat, body) in zip(names, pairs):
            for channel, x in (("seat_acc", seat), ("body_acc", body)):
                check_values(channel, x, name)
            signals = np.stack([seat, body])  # channel 0 seat, 1 body, as WindowCutter.batch stacks them
            if resampled:
                signals = resample_to(signals, dt, self.dt)
            self._check_windows(signals.shape[1], k, name, resampled)
            stacked.append(signals)
        steps = [s.shape[1] for s in stacked]
        check_window_memory(k, names, steps, self.window)
        cut = np.stack([self._windows(s, k) for s in stacked])  # (recordings, K, 2, window)
        if self.baseline is None:
            estimates = self._estimate(cut.reshape(-1, 2, self.window)).reshape(len(pairs), k, 2)
            check_estimates(estimates, names, stacked)
        else:
            estimates = [self._fit(s, k, name) for name, s in zip(names, stacked)]
        p = np.stack([e.mean(axis=0) for e in estimates])
        spread = np.stack([e.std(axis=0) for e in estimates])  # of the K window estimates; 0 for K = 1
        table = pd.DataFrame(
            {
                "recording": names,
                "steps": steps,
                "windows": [len(e) for e in estimates],
                "p1": p[:, 0],
                "p1_std": spread[:, 0],
                "p2": p[:, 1],
                "p2_std": spread[:, 1],
                "m3_from_p1": self.car.c3 / p[:, 0],
                "m3_from_p2": self.car.k3 / p[:, 1],
            },
            columns=COLUMNS[:-1],
        )
        step = max(1, CHUNK // k)  # recordings at a time: their spectra stay within a chunk's memory
        band = self.reference.band
        features = [F.channel_features(cut[i : i + step], self.dt, band) for i in range(0, len(cut), step)]
        return self._flag(table, p, np.concatenate(features), k)

    def _flag(self, table: pd.DataFrame, p: np.ndarray, features: np.ndarray, k: int) -> pd.DataFrame:
        """The flag column (codes joined by commas, empty when none), and one EstimateWarning per kind of flag,
        also in ``table.attrs["warnings"]`` (docs/predict.md, "Flags")."""
        names, n = list(table.recording), len(table)
        lines = []
        outside = self.trained.outside(p)
        if outside.any():
            lines.append(F.range_warning(outside, names, self.trained))
        channels = self.reference.outside(features, k)
        if channels.any():
            lines.append(F.channels_warning(channels, names, self.reference))
        error, k_rows, values = F.run_error(self.record, k)
        large = error is None or error > F.RUN_ERROR_LIMIT
        if large:
            lines.append(F.run_error_warning(error, k_rows, values, n))
        table["flag"] = [
            ",".join(code for code, on in ((F.RANGE, o), (F.CHANNELS, c), (F.RUN_ERROR, large)) if on)
            for o, c in zip(outside, channels)
        ]
        table.attrs["warnings"] = lines
        for line in lines:
            warnings.warn(line, EstimateWarning, stacklevel=3)
        return table

    def _fit(self, signals: np.ndarray, k: int, name) -> np.ndarray:
        """A baseline's estimates of one recording (2, n) at the run's dt, float64 (K, 2) (model.base.Baseline:
        its own windows or one fit of the whole recording), re-integrated as the run's data.measurement says."""
        try:
            estimates = self.baseline.estimate(*signals, self.dt, self.measurement, self.window, k)
        except ConfigError as exc:
            allowed = f"a recording long enough for the run's baseline ({exc})"
            raise InputError(f"recording {name!r}", allowed=allowed) from None
        if not np.isfinite(estimates).all():
            raise InputError(
                f"recording {name!r}",
                allowed=f"accelerations of a car on a road: the least-squares fit of the run's baseline is not defined "
                f"(p1 = {np.nanmean(estimates[:, 0]):g}, p2 = {np.nanmean(estimates[:, 1]):g}; its regressors "
                "vanish or are dependent, a constant or zero recording?)",
            )
        return estimates

    def _check_dt(self, dt, resample: bool) -> float:
        dt = check_dt(dt, "dt", "a finite sampling interval > 0 in seconds", InputError, text=True)
        if abs(dt - self.dt) <= DT_RTOL * self.dt:
            return self.dt
        if not resample:
            raise InputError(
                "dt",
                dt,
                f"the run's data.dt = {self.dt:g} s within {DT_RTOL:g} relative, or resample=true to resample to the "
                "run's rate",
            )
        _ratio(dt, self.dt)  # fails here, before any work, if no fraction is close enough
        return dt

    def _check_windows(self, n: int, k: int, name, resampled: bool) -> None:
        """A recording of n steps (at the run's dt) offers at least one window and k distinct window starts."""
        w = self.window
        after = " after resampling to the run's dt" if resampled else ""
        if n < w:
            raise InputError(
                f"recording {name!r}",
                Shown(f"{n} steps{after}"),
                f"at least the run's data.window = {w} steps ({w * self.dt:g} s)",
            )
        if k > n - w + 1:
            raise InputError(
                "windows",
                k,
                f"1 to {n - w + 1} for recording {name!r}: its {n} steps{after} offer {n - w + 1} distinct starts of a "
                f"{w}-step window",
            )

    def _windows(self, signals: np.ndarray, k: int) -> np.ndarray:
        """(K, channels, window) windows at starts 0, ..., n - window, evenly spaced (integer division: distinct
        whenever K <= n - window + 1, which _check_windows ensures)."""
        starts = window_starts(signals.shape[1], self.window, k)
        return np.lib.stride_tricks.sliding_window_view(signals, self.window, axis=1)[:, starts].transpose(1, 0, 2)

    @torch.no_grad()
    def _estimate(self, windows: np.ndarray) -> np.ndarray:
        """(n, 2, window) float64 -> (n, 2) float64 estimates, in chunks."""
        self.net.eval()
        out = [
            self.net(torch.from_numpy(windows[i : i + CHUNK].astype(np.float32))).numpy()
            for i in range(0, len(windows), CHUNK)
        ]
        return np.concatenate(out).astype(np.float64)


def _ratio(dt_from: float, dt_to: float) -> Fraction:
    """up / down, the resampling factor of the sample rate: dt_from / dt_to as a small fraction."""
    ratio = Fraction(dt_from / dt_to).limit_denominator(MAX_DENOMINATOR)
    if ratio == 0 or abs(float(ratio) * dt_to / dt_from - 1) > RATIO_RTOL:
        raise InputError(
            "dt",
            dt_from,
            f"a step that resamples to the run's data.dt = {dt_to:g} s (a fraction with a denominator up to "
            f"{MAX_DENOMINATOR} within {RATIO_RTOL:g} of their ratio)",
        )
    return ratio


def resample_to(x: np.ndarray, dt_from: float, dt_to: float) -> np.ndarray:
    """x (..., n) sampled every dt_from seconds, resampled along its last axis to every dt_to seconds with
    scipy.signal.resample_poly (anti-aliasing FIR, no phase shift). padtype "line" extends each end by a
    fitted line rather than zeros, so the first and last windows (which every K includes) see no step at the
    edge."""
    r = _ratio(dt_from, dt_to)
    if r == 1:
        return np.asarray(x, dtype=np.float64)
    return resample_poly(x, r.numerator, r.denominator, axis=-1, padtype="line")
