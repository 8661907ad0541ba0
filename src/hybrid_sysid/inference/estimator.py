"""A trained run as a tool: estimate p1 = C3 / m3, p2 = K3 / m3 and the seat mass m3 of recordings.

``load_estimator(run_dir).predict(seat_acc, body_acc, dt)`` cuts K evenly spaced windows from each recording,
gives them to the run's network exactly as training did (float32, shaped (batch, 2, data.window), channel 0
seat, channel 1 body; eval mode, no gradients) and averages the K estimates. The command
``hybrid-sysid-predict`` (hybrid_sysid.cli.predict) only reads files and prints; it calls this same code.
A least-squares baseline run (``baseline=ls_*``) estimates with its fit instead of a network. Each row carries
flags (hybrid_sysid.inference.flags) that say when not to trust it, with one warning per kind.
"""

from __future__ import annotations

import json
import math
import warnings
from fractions import Fraction
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd
import torch
from omegaconf import DictConfig, OmegaConf
from scipy.signal import resample_poly

from hybrid_sysid.baselines.least_squares import LeastSquaresFit, fit_p
from hybrid_sysid.config.validation import available_memory
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data.spec import check_filter_fits
from hybrid_sysid.inference import flags as F
from hybrid_sysid.physics import DEFAULT_MEASUREMENT, QuarterCar, relative_states
from hybrid_sysid.runs.records import RECORD
from hybrid_sysid.runs.rundir import CHECKPOINTS, CONFIG, RunDir
from hybrid_sysid.training.build import build_baseline, build_model

DT_RTOL = 1e-9  # a recording's dt counts as the run's data.dt within this relative difference
# The resampling ratio is a fraction with a denominator up to MAX_DENOMINATOR; the rate it gives may miss the
# run's rate by RATIO_RTOL. A time scale off by e scales p1 by (1 + e) and p2 by (1 + e)^2: 1e-4 is far below
# what any trained estimator resolves.
MAX_DENOMINATOR = 1000
RATIO_RTOL = 1e-4
CHUNK = 4096  # windows per forward pass, so long recordings need bounded memory
FLOAT32_MAX = float(np.finfo(np.float32).max)  # the network reads float32: larger magnitudes become inf
COLUMNS = ["recording", "steps", "windows", "p1", "p1_std", "p2", "p2_std", "m3_from_p1", "m3_from_p2", "flag"]


class InputError(ValueError):
    """Input the estimator cannot use; the message names the item, the value and what is allowed."""


class EstimateWarning(UserWarning):
    """An estimate not to trust (a flag of docs/predict.md); the message says which recordings and why."""


def load_estimator(run_dir: str | Path, checkpoint: str | Path | None = None) -> "Estimator":
    """The trained network of a run directory written by ``hybrid-sysid``.

    ``checkpoint``: None takes checkpoints/best.ckpt (what the run's metrics were computed with) or, when the
    run never validated, last.ckpt; "best", "last" or a path pick one. A directory without a config or
    checkpoint raises InputError (a ValueError) in one line. A baseline run (``baseline=ls_*``: no network)
    estimates with its least-squares fit, built from its config by the package's allow-listed builder
    (``checkpoint`` is then ignored). The run's metrics.json gives its own test error (the flag run_error).
    """
    run = RunDir(run_dir)
    if not run.config_file.is_file():
        raise InputError(f"run = {run.path} has no {CONFIG}; allowed: a run directory written by hybrid-sysid")
    try:
        cfg = OmegaConf.load(run.config_file)
    except Exception as exc:  # noqa: BLE001 - yaml's own errors are many classes; the message says which
        raise InputError(f"run = {run.path}: cannot read {CONFIG} ({type(exc).__name__}: {exc})") from None
    record = _record(run)
    if OmegaConf.select(cfg, "baseline", default=None) is not None:
        net, baseline = None, _baseline(cfg, run)
    else:
        net, baseline = _network(cfg, _checkpoint_path(run, checkpoint), run), None
    try:
        return Estimator(net, cfg, baseline=baseline, record=record)
    except Exception as exc:  # noqa: BLE001 - the data section, read for the trained range, lacks or mistypes keys
        raise InputError(
            f"run = {run.path}: its {CONFIG} is damaged ({type(exc).__name__}: {' '.join(str(exc).split())})"
        ) from None


def _record(run: RunDir) -> dict | None:
    """The run's metrics.json, None when it is missing or unreadable (its test error is then unknown)."""
    try:
        record = json.loads((run.path / RECORD).read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def _baseline(cfg: DictConfig, run: RunDir) -> LeastSquaresFit:
    """The run's least-squares fit, built as the run built it (build_baseline: a _target_ outside the package's
    allow-list is refused before anything is imported)."""
    return _built(build_baseline, cfg, run)


def _built(builder, cfg: DictConfig, run: RunDir):
    """``builder(cfg)`` (the training code's own builders, which refuse a _target_ outside the package's allow-list),
    its failures as one InputError naming the run."""
    try:
        return builder(cfg)
    except ConfigError as exc:
        raise InputError(f"run = {run.path}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - a config that parses but lacks or mistypes keys
        raise InputError(
            f"run = {run.path}: its {CONFIG} is damaged ({type(exc).__name__}: {' '.join(str(exc).split())})"
        ) from None


def _checkpoint_path(run: RunDir, checkpoint) -> Path:
    names = CHECKPOINTS if checkpoint is None else (f"{checkpoint}.ckpt",)
    if checkpoint is not None and str(checkpoint) not in ("best", "last"):
        candidates = [Path(checkpoint)]
    else:
        candidates = [run.checkpoints / n for n in names]
    for path in candidates:
        if path.is_file():
            return path
    raise InputError(
        f"run = {run.path} has no checkpoint {' or '.join(str(p) for p in candidates)}; allowed: "
        "a run that trained a network (hybrid-sysid writes checkpoints/best.ckpt and last.ckpt)"
    )


def _network(cfg: DictConfig, path: Path, run: RunDir) -> torch.nn.Module:
    """The run's network with the checkpoint's weights, built by the code that trained it. The only call into
    the training code: if build_model gains arguments, this is the line to change."""
    model = _built(build_model, cfg, run)  # a class the config names is checked before anything is imported
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)["state_dict"]
    except Exception as exc:  # noqa: BLE001 - torch raises several classes for a truncated or foreign file
        raise InputError(f"checkpoint {path} cannot be read ({type(exc).__name__}: {exc})") from None
    try:
        model.load_state_dict(state)  # keys "net." and "objective.", as the LightningModule saved them
    except RuntimeError as exc:  # another run's checkpoint: torch lists every mismatched key, one line each
        raise InputError(
            f"checkpoint {path} does not fit the run's model.net ({cfg.model.net._target_}): {str(exc).splitlines()[0]}"
        ) from None
    return model.net


class Estimator:
    """A run's network (or least-squares baseline) and what it needs to read a recording: the run's dt, window,
    car and measurement, its trained range and its own test error (``record``, its metrics.json)."""

    def __init__(
        self,
        net: torch.nn.Module | None,
        config: DictConfig,
        baseline: LeastSquaresFit | None = None,
        record: dict | None = None,
    ):
        if (net is None) == (baseline is None):
            raise ValueError("an Estimator takes a network or a baseline, one of them")
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
                raise InputError(f"the run's data spec cannot be simulated for the channel check: {exc}") from None
        return self._reference

    def predict(
        self, seat_acc, body_acc, dt: float, windows: int = 8, resample: bool = False, names: Sequence | None = None
    ) -> pd.DataFrame:
        """Estimates per recording: p1, p2 (1/s, 1/s^2) averaged over ``windows`` windows, their std over the
        windows, and m3 (kg) from each, m3 = C3 / p1 and K3 / p2 for the run's car.

        seat_acc, body_acc: float arrays in m/s^2, 1-D (one recording), 2-D (recordings, steps) or a list of
        1-D arrays (recordings of different lengths). dt: their sampling interval in s; it must equal the run's
        data.dt unless ``resample`` (then scipy's polyphase filter brings them to the run's rate). The K window
        starts are evenly spaced over each recording, first at 0, last at the end. ``names`` label the
        recordings (default 0, 1, ...). Bad input raises InputError (a ValueError).

        The column ``flag`` says why not to trust a row (range, channels, run_error; empty when none); each kind
        also raises one EstimateWarning and is listed in ``table.attrs["warnings"]`` (docs/predict.md, "Flags").
        """
        if isinstance(windows, bool) or not isinstance(windows, (int, np.integer)) or windows < 1:
            raise InputError(f"windows = {windows!r} is not allowed: an integer >= 1")
        recordings = _recordings(seat_acc, body_acc)
        names = list(range(len(recordings))) if names is None else list(names)
        if len(names) != len(recordings):
            raise InputError(f"names has {len(names)} items for {len(recordings)} recordings: one name each")
        dt = self._check_dt(dt, resample)
        k, resampled = int(windows), dt != self.dt
        stacked = []  # every check passes before any window is cut
        for name, (seat, body) in zip(names, recordings):
            for channel, x in (("seat_acc", seat), ("body_acc", body)):
                _check_values(channel, x, name)
            signals = np.stack([seat, body])  # channel 0 seat, 1 body, as WindowCutter.batch stacks them
            if resampled:
                signals = resample_to(signals, dt, self.dt)
            self._check_windows(signals.shape[1], k, name, resampled)
            stacked.append(signals)
        steps = [s.shape[1] for s in stacked]
        self._check_memory(k, names, steps)
        cut = np.stack([self._windows(s, k) for s in stacked])  # (recordings, K, 2, window)
        if self.baseline is None:
            estimates = self._estimate(cut.reshape(-1, 2, self.window)).reshape(len(recordings), k, 2)
            _check_estimates(estimates, names, stacked)
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
            lines.append(F.range_warning(outside, names, self.trained, self.baseline is None))
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
        """A baseline's estimates of one recording (2, n) at the run's dt, float64 (K, 2): per window (span
        "window": the K windows the network would see, their regressors integrated over the whole recording
        from t0 and cropped, as the run's data module cuts them) or one fit of the whole recording (span
        "series": (1, 2)). The run's data.measurement decides how the accelerations are re-integrated."""
        fit, (seat, body) = self.baseline, signals
        rel_vel, rel_disp = relative_states(seat, body, self.dt, self.measurement)
        if fit.span == "series":
            try:
                check_filter_fits(fit.taps if fit.fir is not None else None, len(seat), "baseline.taps", "its steps")
            except ConfigError as exc:
                raise InputError(f"recording {name!r} is too short for the run's band-pass: {exc}") from None
            rows = [seat[None], rel_vel[None], rel_disp[None]]
        else:
            rows = list(self._windows(np.stack([seat, rel_vel, rel_disp]), k).transpose(1, 0, 2))
        estimates = fit_p(*rows, fit.fir, fit.car)
        if not np.isfinite(estimates).all():
            raise InputError(
                f"recording {name!r}: the least-squares fit of the run's baseline is not defined (p1 = "
                f"{np.nanmean(estimates[:, 0]):g}, p2 = {np.nanmean(estimates[:, 1]):g}): its regressors vanish or "
                "are dependent (a constant or zero recording?); allowed: accelerations of a car on a road"
            )
        return estimates

    def _check_dt(self, dt, resample: bool) -> float:
        given = dt
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            dt = math.nan
        if not (math.isfinite(dt) and dt > 0):
            raise InputError(f"dt = {given!r} is not allowed: a finite sampling interval > 0 in seconds")
        if abs(dt - self.dt) <= DT_RTOL * self.dt:
            return self.dt
        if not resample:
            raise InputError(
                f"dt = {dt:g} s differs from the run's data.dt = {self.dt:g} s; allowed: within "
                f"{DT_RTOL:g} relative, or pass resample=true to resample to the run's rate"
            )
        _ratio(dt, self.dt)  # fails here, before any work, if no fraction is close enough
        return dt

    def _check_windows(self, n: int, k: int, name, resampled: bool) -> None:
        """A recording of n steps (at the run's dt) offers at least one window and k distinct window starts."""
        w = self.window
        after = " after resampling to the run's dt" if resampled else ""
        if n < w:
            raise InputError(
                f"recording {name!r} has {n} steps{after}; allowed: at least the run's "
                f"data.window = {w} steps ({w * self.dt:g} s)"
            )
        if k > n - w + 1:
            raise InputError(
                f"windows = {k} is not allowed for recording {name!r}: its {n} steps{after} offer "
                f"{n - w + 1} distinct starts of a {w}-step window; allowed: 1 to {n - w + 1}"
            )

    def _check_memory(self, k: int, names: list, steps: list[int]) -> None:
        """The windows of every recording, cut and stacked, fit in the memory available (window_bytes)."""
        need, available = window_bytes(k * len(names), self.window), available_memory()
        if available is None or need <= available:
            return
        fit = max_windows(available, self.window) // len(names)
        longest = int(np.argmax(steps))
        which = (
            f"recording {names[0]!r} ({steps[0]} steps)"
            if len(names) == 1
            else f"{len(names)} recordings (the longest, {names[longest]!r}, {steps[longest]} steps)"
        )
        raise InputError(
            f"windows = {k} is not allowed for {which}: {k * len(names)} windows of 2 x {self.window} steps "
            f"need {need / 2**30:.3g} GiB of memory (float64, cut and stacked, plus a float32 copy of up to "
            f"{CHUNK} windows) and {available / 2**30:.3g} GiB is available; allowed: "
            + (f"1 to {fit}" if fit >= 1 else "fewer recordings per call, or more memory")
        )

    def _windows(self, signals: np.ndarray, k: int) -> np.ndarray:
        """(K, channels, window) windows at starts 0, ..., n - window, evenly spaced (integer division: distinct
        whenever K <= n - window + 1, which _check_windows ensures)."""
        n, w = signals.shape[1], self.window
        starts = np.arange(k) * (n - w) // max(k - 1, 1)
        return np.lib.stride_tricks.sliding_window_view(signals, w, axis=1)[:, starts].transpose(1, 0, 2)

    @torch.no_grad()
    def _estimate(self, windows: np.ndarray) -> np.ndarray:
        """(n, 2, window) float64 -> (n, 2) float64 estimates, in chunks."""
        self.net.eval()
        out = [
            self.net(torch.from_numpy(windows[i : i + CHUNK].astype(np.float32))).numpy()
            for i in range(0, len(windows), CHUNK)
        ]
        return np.concatenate(out).astype(np.float64)


def window_bytes(n_windows: int, window: int) -> int:
    """Bytes that n_windows windows of 2 x window steps take while they are estimated: float64 twice (each
    recording's cut windows and the stack of all of them), plus the float32 copy of one chunk."""
    return n_windows * 2 * window * 8 * 2 + min(n_windows, CHUNK) * 2 * window * 4


def max_windows(available: int, window: int) -> int:
    """The most windows whose window_bytes fit in ``available`` bytes."""
    per = 2 * window  # values per window
    n = available // (per * 20)  # up to CHUNK windows, each has its float32 copy
    return n if n < CHUNK else (available - CHUNK * per * 4) // (per * 16)


def _check_values(channel: str, x: np.ndarray, name) -> None:
    """Every value finite and within float32's range, which the network reads (beyond it: inf, then NaN)."""
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise InputError(
            f"{channel} of recording {name!r} holds {x[bad[0]]} at step {bad[0]}: every value must be finite"
        )
    big = np.flatnonzero(np.abs(x) > FLOAT32_MAX)
    if big.size:
        raise InputError(
            f"{channel} of recording {name!r} holds {x[big[0]]:g} at step {big[0]}: beyond float32's range, in "
            f"which the network reads it; allowed: magnitudes up to {FLOAT32_MAX:g}"
        )


def _check_estimates(estimates: np.ndarray, names: list, stacked: list[np.ndarray]) -> None:
    """Estimates (recordings, K, 2) all finite: values inside float32's range may still overflow the network's
    float32 arithmetic, which then returns NaN or inf rather than an estimate."""
    for name, e, signals in zip(names, estimates, stacked):
        if not np.isfinite(e).all():
            channel = int(np.argmax(np.abs(signals).max(axis=1)))
            raise InputError(
                f"recording {name!r}: the network's estimate is not finite (p1 = {e[:, 0].mean():g}, "
                f"p2 = {e[:, 1].mean():g}): its values, up to {np.abs(signals).max():g} m/s^2 in "
                f"{('seat_acc', 'body_acc')[channel]}, overflow the network's float32 arithmetic; allowed: "
                "accelerations of the magnitude the run was trained on"
            )


def _recordings(seat_acc, body_acc) -> list[tuple[np.ndarray, np.ndarray]]:
    """(seat, body) float64 1-D pairs, one per recording, with equal lengths checked."""

    def real(name, x):
        """x unchanged; bool and complex arrays would lose what they mean when read as float64."""
        dtype = np.asarray(x).dtype
        if dtype.kind in "bc":
            raise InputError(
                f"{name} has dtype {dtype}; allowed: real numbers in m/s^2 (a float or integer "
                "array), not bool or complex"
            )
        return x

    def split(name, x) -> list[np.ndarray]:
        try:
            if isinstance(x, (list, tuple)) and x and np.ndim(x[0]) == 1:
                return [np.asarray(real(f"{name}[{i}]", r), dtype=np.float64) for i, r in enumerate(x)]
            x = np.asarray(real(name, x), dtype=np.float64)
        except InputError:
            raise
        except (TypeError, ValueError) as exc:
            raise InputError(f"{name} cannot be read as numbers ({exc}); allowed: float arrays in m/s^2") from None
        if x.ndim not in (1, 2) or x.size == 0:
            raise InputError(
                f"{name} has shape {x.shape}; allowed: 1-D (one recording), 2-D (recordings, steps) "
                "or a list of 1-D arrays, not empty"
            )
        return [x] if x.ndim == 1 else list(x)

    seat, body = split("seat_acc", seat_acc), split("body_acc", body_acc)
    if len(seat) != len(body):
        raise InputError(f"seat_acc holds {len(seat)} recordings and body_acc {len(body)}: they must be equal")
    for i, (s, b) in enumerate(zip(seat, body)):
        if s.shape != b.shape or s.ndim != 1:
            raise InputError(
                f"recording {i}: seat_acc has shape {s.shape} and body_acc {b.shape}; allowed: "
                "two 1-D arrays of one length"
            )
    return list(zip(seat, body))


def _ratio(dt_from: float, dt_to: float) -> Fraction:
    """up / down, the resampling factor of the sample rate: dt_from / dt_to as a small fraction."""
    ratio = Fraction(dt_from / dt_to).limit_denominator(MAX_DENOMINATOR)
    if ratio == 0 or abs(float(ratio) * dt_to / dt_from - 1) > RATIO_RTOL:
        raise InputError(
            f"dt = {dt_from:g} s cannot be resampled to the run's data.dt = {dt_to:g} s: no fraction "
            f"with a denominator up to {MAX_DENOMINATOR} is within {RATIO_RTOL:g} of their ratio"
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
