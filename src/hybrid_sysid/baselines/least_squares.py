"""Classical least squares for (p1, p2): no network, no training, plain numpy in float64.

The seat equation z''_k = -p1 rel_vel_k - p2 rel_disp_k (physics.relative_states) is linear in p, so each
recording (or each window) gives p by regressing the seat acceleration on (-rel_vel, -rel_disp). With
``data.measurement=consistent`` it holds to rounding on clean data, so the fit returns the true p; under
sensor noise the regressors are the re-integrated noisy accelerations (errors in variables), which biases
the plain fit, and a band-pass applied to all three signals (filters.py) removes most of that noise.

``LeastSquaresFit`` meets the baselines' protocol (``hybrid_sysid.model.base.Baseline``: ``predict_split``,
``check_lengths``, ``estimate``), so the training layer scores it like a network and a run directory of it
estimates recordings; a run with ``baseline=`` set builds it and skips Lightning.
"""

from __future__ import annotations

import time

import numpy as np

from hybrid_sysid.baselines.fixes import fit_fixed
from hybrid_sysid.core.checks import bad, check_choice
from hybrid_sysid.core.options import FILTERS, SPANS, UNKNOWNS
from hybrid_sysid.data import SPLITS  # the split codes that seed the evaluation noise
from hybrid_sysid.data.spec import check_filter_fits, window_starts
from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.faults import fix_code
from hybrid_sysid.physics.faults.skew import check_skew_max
from hybrid_sysid.physics.filters import bandpass_taps, check_bandpass, fir_valid

_SERIES_CHUNK = 256  # recordings per chunk of the series variant: bounds memory, fixes the noise streams


def lstsq_rows(a: np.ndarray, b: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per row i, the (c1, c2) minimising ||y_i - c1 a_i - c2 b_i||, for arrays (n, T); returns (n, 2) float64.

    A two-column QR by Gram-Schmidt with one re-orthogonalisation, vectorised over rows: stable where the
    normal equations would square the condition number (rel_vel and rel_disp differ in scale by ~sqrt(p2)
    and are far from orthogonal on smooth roads). Rows with a zero or dependent column give NaN.
    """
    a, b, y = (np.asarray(v, dtype=np.float64) for v in (a, b, y))
    with np.errstate(invalid="ignore", divide="ignore"):
        r11 = np.linalg.norm(a, axis=-1)
        q1 = a / r11[:, None]
        r12 = np.einsum("ij,ij->i", q1, b)
        u = b - r12[:, None] * q1
        s = np.einsum("ij,ij->i", q1, u)  # second pass: what rounding left of q1 in u
        u -= s[:, None] * q1
        r12 += s
        r22 = np.linalg.norm(u, axis=-1)
        q2 = u / r22[:, None]
        c2 = np.einsum("ij,ij->i", q2, y) / r22
        c1 = (np.einsum("ij,ij->i", q1, y) - r12 * c2) / r11
    out = np.stack([c1, c2], axis=-1)
    out[~(r11 > 0) | ~(r22 > 1e-13 * np.linalg.norm(b, axis=-1))] = np.nan  # NaN compares False: caught too
    return out


def fit_p(
    seat: np.ndarray,
    rel_vel: np.ndarray,
    rel_disp: np.ndarray,
    taps: np.ndarray | None = None,
    car: tuple[float, float] | None = None,
) -> np.ndarray:
    """(p1, p2) per row from z'' = -p1 rel_vel - p2 rel_disp, after an optional FIR on all three signals.

    ``car`` = (C3, K3) known (the paper's premise: only the seat mass m3 is unknown): one parameter per row,
    q = 1 / m3, from z'' = -q (C3 rel_vel + K3 rel_disp), and p = q (C3, K3)."""
    if taps is not None:
        seat, rel_vel, rel_disp = (fir_valid(v, taps) for v in (seat, rel_vel, rel_disp))
    rel_vel, rel_disp = np.asarray(rel_vel, dtype=np.float64), np.asarray(rel_disp, dtype=np.float64)
    if car is None:
        return lstsq_rows(-rel_vel, -rel_disp, seat)
    u = -(car[0] * rel_vel + car[1] * rel_disp)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.einsum("ij,ij->i", u, np.asarray(seat, dtype=np.float64)) / np.einsum("ij,ij->i", u, u)
    return q[:, None] * np.asarray(car, dtype=np.float64)


class LeastSquaresFit:
    """Least-squares (p1, p2) per recording, evaluated like a trained network.

    span "window": per evaluation window, on the regressors the hybrid objective gets: the data module's
        batch rel_vel / rel_disp (integrated over the whole recording from t0, cropped, plus the window's
        noise re-integrated from the window start). With K windows per recording (evaluation.windows), the
        K estimates are averaged like a network's predictions.
    span "series": per recording over all its steps, with noise of the given std added to both channels over
        the whole recording (seeded per (seed, split), as the data module does for windows) and re-integrated
        from t0. It sees no windows, so it ignores K: every K gives the same one estimate per recording.
    filter "bandpass": the same zero-phase FIR band-pass [low_hz, high_hz] (``taps`` long, dt the data's step)
        on the seat acceleration and both regressors before the fit; the filter's edges are dropped.
        The defaults, 4-20 Hz and 151 taps at dt = 5 ms, keep the seat resonance and drop the drift of
        integrated noise (docs/baselines.md: how they were chosen).
    unknown "p": both p1 and p2 fitted; "m3": C3 and K3 known (``c3``, ``k3``, the car's), only m3 fitted,
        so p = (C3, K3) / m3 is one parameter (the paper's own premise).
    fix: the classical fix of a recording fault (baselines.fixes: "gain", "skew", "hardening" or a registered
        fault's own, physics.faults.fixes), one more parameter fitted with p; per band-passed window, both p
        unknown. ``skew_max``: the offsets "skew" tries.
    """

    fit_seconds = 0.0  # wall time spent in predict_split: a baseline's only work (each instance its own)
    fit_cpu_seconds = 0.0  # its CPU time, which load on the machine hardly moves (launch.time_left compares it)

    def __init__(
        self,
        span: str = "window",
        filter: str = "none",
        low_hz: float = 4.0,
        high_hz: float = 20.0,
        taps: int = 151,
        dt: float = 0.005,
        unknown: str = "p",
        c3: float | None = None,
        k3: float | None = None,
        fix: str = "none",
        skew_max: float = 0.02,
    ):
        check_choice("span", span, SPANS)
        check_choice("filter", filter, FILTERS)
        check_choice("unknown", unknown, UNKNOWNS)
        fix_code(fix)  # a registered fix (physics.faults.fixes), else a ConfigError naming fix
        if fix != "none" and (span, filter, unknown) != ("window", "bandpass", "p"):
            bad("fix", fix, "none unless span = window, filter = bandpass and unknown = p (a fix is per window)")
        for key, value in (("c3", c3), ("k3", k3)) if unknown == "m3" else ():
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                bad(key, value, f"must be finite and > 0 with unknown = m3 (the car's constant, ${{car.{key}}})")
        self.car = (float(c3), float(k3)) if unknown == "m3" else None
        check_bandpass(low_hz, high_hz, taps, dt)  # checked even when unused, so a typo never waits
        self.span, self.filter = span, filter
        self.low_hz, self.high_hz, self.taps, self.dt = float(low_hz), float(high_hz), int(taps), float(dt)
        self.fir = bandpass_taps(low_hz, high_hz, taps, dt) if filter == "bandpass" else None
        self.fix, self.skew_max = fix, check_skew_max(skew_max)
        self.fit_seconds = self.fit_cpu_seconds = 0.0  # time spent in predict_split: a baseline's only work

    def check_lengths(self, window: int, n_steps: int) -> None:
        """The band-pass must leave enough samples of what it filters (a window or the whole recording)."""
        if self.fir is None:
            return
        length, key = (window, "data.window") if self.span == "window" else (n_steps, "data.n_steps")
        check_filter_fits(self.taps, length, "taps", key)

    def estimate(self, seat, body, dt: float, measurement: str, window: int, windows: int) -> np.ndarray:
        """(K, 2) float64 estimates of one recording: per window (span "window": ``windows`` = K evenly spaced
        windows, their regressors integrated over the whole recording from t0 and cropped, as the data module
        cuts them) or one fit of the whole recording (span "series": (1, 2)). NaN where the fit is not defined
        (regressors that vanish or are dependent)."""
        seat = np.asarray(seat, dtype=np.float64)
        rel_vel, rel_disp = relative_states(seat, body, dt, measurement)
        if self.span == "series":
            self.check_lengths(window, len(seat))
            rows = [seat[None], rel_vel[None], rel_disp[None]]
        else:
            starts = window_starts(len(seat), window, windows)
            body = np.asarray(body, dtype=np.float64)
            rows = [np.stack([x[s : s + window] for s in starts]) for x in (seat, rel_vel, rel_disp, body)]
            if self.fix != "none":
                return self._fixed(*rows, dt, measurement)
            rows = rows[:3]
        return fit_p(*rows, self.fir, self.car)

    def _fixed(self, seat, rel_vel, rel_disp, body, dt, measurement) -> np.ndarray:
        return fit_fixed(self.fix, seat, body, rel_vel, rel_disp, dt, measurement, self.fir, self.skew_max)

    def predict_split(self, dm, split: str, noise_std: float, limit: int | None = None, windows: int = 1):
        """Estimates and truth, float64 (n, 2), one row per recording (model.base.SplitPredictor)."""
        start, cpu = time.perf_counter(), time.process_time()
        dm.setup()
        self.check_lengths(dm.window, dm.data.n_steps)
        if self.span == "window":
            pred, true = self._windows(dm, split, noise_std, limit, windows)
        else:
            pred, true = self._series(dm, split, noise_std, limit)
        self.fit_seconds += time.perf_counter() - start
        self.fit_cpu_seconds += time.process_time() - cpu
        return pred, true

    def _windows(self, dm, split, noise_std, limit, windows):
        batch = dm.eval_batch(split, noise_std, limit, windows=windows)
        seat, body = (batch["signals"][:, i].numpy().astype(np.float64) for i in (0, 1))
        regressors = batch["rel_vel"].numpy(), batch["rel_disp"].numpy()
        if self.fix != "none":
            spec = dm.dataset.spec
            p = self._fixed(seat, *regressors, body, spec.dt, spec.measurement)
        else:
            p = fit_p(seat, *regressors, self.fir, self.car)
        # the batch holds each recording's K windows in a row (data module); mean over them as for a network
        pred = p.reshape(-1, windows, 2).mean(axis=1)
        true = batch["params"].numpy().astype(np.float64).reshape(-1, windows, 2)[:, 0]
        return pred, true

    def _series(self, dm, split, noise_std, limit):
        ds, rows = dm.dataset, dm.rows(split)
        rows = rows if limit is None else rows[:limit]
        code = SPLITS.index(split)
        preds = []
        for c in range(0, len(rows), _SERIES_CHUNK):
            r = rows[c : c + _SERIES_CHUNK]
            seat = ds.seat_acc[r].astype(np.float64)
            body = ds.body_acc[r].astype(np.float64)
            if noise_std > 0:  # one generator per chunk of the split's rows: the same noise whatever the limit
                rng = np.random.default_rng([dm.seed, code, 3000, c // _SERIES_CHUNK])
                noise = noise_std * rng.standard_normal((len(r), 2, seat.shape[1]))
                seat, body = seat + noise[:, 0], body + noise[:, 1]
            rel_vel, rel_disp = relative_states(seat, body, ds.spec.dt, ds.spec.measurement)
            preds.append(fit_p(seat, rel_vel, rel_disp, self.fir, self.car))
        # float32 truth like the network's batches, so both kinds of run score against identical labels
        true = ds.params[rows].astype(np.float32).astype(np.float64)
        return np.concatenate(preds) if preds else np.zeros((0, 2)), true
