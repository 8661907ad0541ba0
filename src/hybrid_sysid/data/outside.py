"""The fit of the seat over the rest of a window's recording: the target of ``objective=cross_segment``
(hybrid_sysid.model.cross_segment), computed with the batches.

Per batch row: the whole clean recording plus fresh Gaussian noise of the row's std, on both channels. Two fits of
the samples outside the window [start, start + W), as the objective's ``outside_target`` asks:

"ls": the band-passed least squares. The recording is re-integrated from t0 by its measurement, band-passed
('valid') and fitted (physics.seat_fit) on the filtered samples whose whole FIR support lies outside the window.
Those samples read no sample of the window. The noise the window's own samples add to the regressors after it
integrates to a constant in rel_vel and a constant and a ramp in rel_disp, which a symmetric band-pass of zero sum
removes. So the fit's noise is independent of the window's, as in a recording whose sensor noise is white.

"eiv": the errors-in-variables maximum likelihood of the two outside segments joined, started from the "ls" fit
(data.outside_joined).

Under a recording fault (``fix``, the fault's fix as the anchored estimator takes it) the "eiv" target is the
likelihood fit with that fix, started from least squares with it (physics.faults, physics.eiv). The plain fits
of a faulted recording are biased (skew: 11.5% on p1, clean; benchmarks/README.md), and a label-free network then
learns the bias. The joined fit has no fix, so the fixed fit takes the longer outside segment alone, cropped to
(n - W) // 2 samples: every row's piece then has one length, and the rows are fitted together.
"""

from __future__ import annotations

import numpy as np
import torch

from hybrid_sysid.core.checks import bad, check_choice
from hybrid_sysid.core.options import OUTSIDE_TARGETS as TARGETS
from hybrid_sysid.data.outside_joined import fit_joined
from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.eiv import eiv_model, fit_eiv
from hybrid_sysid.physics.eiv.fit import fix_samples
from hybrid_sysid.physics.faults import fix_code
from hybrid_sysid.physics.seat_fit import fit_seat

CHUNK = 256  # rows filtered at once: bounds the float64 work arrays of a large evaluation batch (~30 MB)
# The likelihood fit corrects least squares' attenuation towards zero. A correction beyond this factor means the
# noise holds more of the regressors' power than the motion does. There (smooth roads at noise 0.1) the likelihood
# has maxima far from the truth with a small se: p1 off by 1-5 times at noise 0.1 (8-9% of the rows), by 0.4-1.2
# times at 0.03 (2-3%). Such a row keeps the least-squares target. Measured on data=default (seat_spread 0.3,
# 3 x 400 rows), the objective's loss at the true p at noise 0.1: limit 2, 0.17-0.20; 3, 0.18-0.21; none, 0.29-0.51;
# least squares, 0.18. At 0.03 every limit gave 0.05, none 0.05-0.12, least squares 0.07.
MAX_CORRECTION = 2.0
SKEW_MAX = 0.02  # s: the skew fix's reach, the anchored estimator's (its likelihood fit's default)


def check_fix_fits(fix: str, target: str | None, n_steps: int, window: int, taps: int, dt: float, measurement: str):
    """The fixed target's segment, (n_steps - window) // 2 samples, must hold the fix's transient and the least-
    squares start's band-pass (``taps``): ConfigError naming n_steps otherwise."""
    if fix == "none" or target != "eiv":
        return
    need = max(taps + 1, fix_samples(fix, eiv_model(measurement), dt, SKEW_MAX))
    if (n_steps - window) // 2 < need:
        bad(
            "n_steps",
            n_steps,
            f"must be >= data.window + {2 * need} = {window + 2 * need}: under the fault, the fit over the samples "
            f"outside a window (objective=cross_segment) takes {need} of them with its {fix} fix",
        )


class OutsideFit:
    """The outside fit of the windows of one dataset: ``fit(rows, starts, std, normals)`` -> {"p_out", "se_out"}.

    ``fir``: the objective's band-pass taps (``outside_fir``); ``target``: the fit, one of TARGETS (its
    ``outside_target``). None is "ls", the fit of a config saved before the objective had a target. The clean
    recordings are the dataset's float32 channels, read as they are stored (no copy until a batch takes its rows).
    """

    def __init__(
        self,
        seat_acc: np.ndarray,
        body_acc: np.ndarray,
        dt: float,
        measurement: str,
        window: int,
        fir,
        target: str | None = None,
        lengths: np.ndarray | None = None,
        fix: str = "none",
    ):
        self.seat, self.body = seat_acc, body_acc
        self.dt, self.measurement, self.window = dt, measurement, window
        self.target = "ls" if target is None else target
        check_choice("target", self.target, TARGETS)
        self.fir = np.asarray(fir, dtype=np.float64)
        self.n_steps = seat_acc.shape[1]
        fix_code(fix)  # a registered fix, else a ConfigError naming fix
        self.fix = fix if self.target == "eiv" else "none"  # least squares' target stays the plain fit
        # a user's recordings of several lengths are zero-padded to the longest (data.recordings): each row is
        # then fitted over its own samples only, rows of one length together
        self.lengths = np.full(len(seat_acc), self.n_steps) if lengths is None else np.asarray(lengths, np.int64)
        check_fix_fits(self.fix, self.target, int(self.lengths.min()), window, len(self.fir), dt, measurement)
        self._fir_fft: dict[int, torch.Tensor] = {}

    def fir_fft(self, n_steps: int) -> tuple[int, torch.Tensor]:
        """The FFT length for recordings of ``n_steps`` and the taps' transform at it. torch's FFT in float64
        takes about a third of numpy's time here (physics.filters.fir_valid's), the larger part of this fit's cost;
        a transform as long as the recording suffices, as the circular wrap-around reaches only the taps - 1 edge
        samples that 'valid' drops."""
        nfft = 1 << int(np.ceil(np.log2(n_steps)))
        if nfft not in self._fir_fft:
            self._fir_fft[nfft] = torch.fft.rfft(torch.from_numpy(self.fir), nfft)
        return nfft, self._fir_fft[nfft]

    def mask(self, starts, n_steps: int | None = None) -> np.ndarray:
        """(B, n_steps - taps + 1) of 1.0 where the filtered sample's FIR support (inputs j .. j + taps - 1) lies
        wholly before or after the window at each start, 0.0 elsewhere (n_steps: the recordings', by default the
        dataset's)."""
        taps = len(self.fir)
        j = np.arange((self.n_steps if n_steps is None else n_steps) - taps + 1)
        s = np.asarray(starts, dtype=np.int64)[:, None]
        return ((j + taps - 1 < s) | (j >= s + self.window)).astype(np.float64)

    def fit(self, rows, starts, std=0.0, normals: np.ndarray | None = None) -> dict[str, torch.Tensor]:
        """The batch's "p_out" and "se_out" (B, 2) float64: the fitted p and its relative standard error (NaN
        and inf where the fit is not defined). ``normals`` (B, 2, n_steps) standard normals on the seat and body
        channels, scaled by ``std`` (a number, or one per row); None: the clean recordings. The "eiv" target keeps
        the "ls" fit of a row where its own is not defined, not converged (``fit_joined``) or more than
        MAX_CORRECTION times away from it."""
        rows, starts = np.asarray(rows, dtype=np.int64), np.asarray(starts, dtype=np.int64)
        stds = np.broadcast_to(np.asarray(std, dtype=np.float64), rows.shape)
        p, se = np.empty((len(rows), 2)), np.empty((len(rows), 2))
        lengths = self.lengths[rows]
        for n in np.unique(lengths):
            same = np.flatnonzero(lengths == n)
            for i in range(0, len(same), CHUNK):
                at = same[i : i + CHUNK]
                seat = self.seat[rows[at], :n].astype(np.float64)
                body = self.body[rows[at], :n].astype(np.float64)
                if normals is not None:
                    seat += stds[at, None] * normals[at, 0, :n]
                    body += stds[at, None] * normals[at, 1, :n]
                p[at], se[at] = self._fit(seat, body, starts[at])
        return {"p_out": torch.from_numpy(p), "se_out": torch.from_numpy(se)}

    def _fit(self, seat: np.ndarray, body: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """fit's, for rows of one length (B, n) in float64."""
        n = seat.shape[1]
        if self.fix != "none":  # the plain least squares only as the fallback of rows whose fixed fit failed
            p_fix, se_fix, ok = self._fixed(seat, body, starts)
            if ok.all():
                return p_fix, se_fix
        rel_vel, rel_disp = relative_states(seat, body, self.dt, self.measurement)
        nfft, fir_fft = self.fir_fft(n)
        spectra = torch.fft.rfft(torch.from_numpy(np.stack([seat, rel_vel, rel_disp])), nfft)
        filtered = torch.fft.irfft(spectra * fir_fft, nfft)[..., len(self.fir) - 1 : n].numpy()
        out = fit_seat(*filtered, weights=self.mask(starts, n))
        p, se = out.p, out.se
        if self.fix != "none":
            return np.where(ok[:, None], p_fix, p), np.where(ok[:, None], se_fix, se)
        if self.target == "eiv":
            model = eiv_model(self.measurement)
            p_eiv, se_eiv, ok = fit_joined(seat, body, starts, self.window, self.dt, model, p0=out.p)
            with np.errstate(invalid="ignore", divide="ignore"):
                ok &= (np.abs(np.log(p_eiv / out.p)) <= np.log(MAX_CORRECTION)).all(axis=1)
            p = np.where(ok[:, None], p_eiv, p)
            se = np.where(ok[:, None], se_eiv, se)
        return p, se

    def _fixed(self, seat: np.ndarray, body: np.ndarray, starts: np.ndarray):
        """The fault's fixed likelihood fit of each row's longer outside segment, its (n - W) // 2 samples nearest
        the window: (p, se, ok), ok where it is defined, converged and within MAX_CORRECTION of its least-squares
        start with the same fix."""
        n = seat.shape[1]
        length = (n - self.window) // 2
        before = starts >= n - starts - self.window  # the segment before the window is the longer one
        first = np.where(before, starts - length, starts + self.window)
        at = first[:, None] + np.arange(length)
        seat, body = np.take_along_axis(seat, at, axis=1), np.take_along_axis(body, at, axis=1)
        rel_vel, rel_disp = relative_states(seat, body, self.dt, self.measurement)
        code = fix_code(self.fix)
        p0 = code.least_squares(seat, body, rel_vel, rel_disp, self.dt, self.measurement, self.fir, SKEW_MAX)
        model = eiv_model(self.measurement)
        fit = fit_eiv(seat, body, self.dt, model=model, p0=p0, fix=self.fix, skew_max=SKEW_MAX)
        with np.errstate(invalid="ignore", divide="ignore"):
            near = (np.abs(np.log(fit.p / p0)) <= np.log(MAX_CORRECTION)).all(axis=1)
        ok = fit.converged & np.isfinite(fit.p).all(axis=1) & (near | ~np.isfinite(p0).all(axis=1))
        return fit.p, fit.se, ok
