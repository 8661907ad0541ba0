"""The errors-in-variables fit of each window as a baseline (``baseline=eiv``, ``baseline=eiv_map``): no network, no
labels, no training. Plain numpy in float64 (physics.eiv holds the fit; this class scores it like a network).

Least squares regresses the seat on regressors that carry the body channel's noise; the errors-in-variables maximum
likelihood treats both channels as noisy and needs only the ratio of their noise variances (``noise_ratio``, 1 in
the simulator). With ``prior`` set, the same likelihood plus a Gaussian prior on log p (MAP), its moments those of
the simulator's draws of the seat (physics.eiv.log_p_prior): the mass range and the seat constants' spread.

Each fit starts from the window's band-passed least squares (physics.seat_fit), which is also what a window whose
likelihood fit is not defined keeps. The model follows the recording: the simulator's exact discrete transfer
function for stepped recordings ("consistent", and "paper", where it is only close), the continuous one for samples
of continuous motion ("continuous") (docs/baselines.md).

With ``fix`` (``estimator=eiv_fix``, ``estimator=eiv_map_fix``: the fault's fix, as ``estimator=ls_fix`` picks it)
a recording fault is one more parameter of the same likelihood (physics.eiv, "Fixes"), and the start is the
band-passed least squares with the same fix (baselines.fixes).
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np

from hybrid_sysid.baselines.fixes import fit_fixed
from hybrid_sysid.core.checks import ConfigError, bad
from hybrid_sysid.data.spec import check_filter_fits, window_starts
from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.eiv import P_HI, P_LO, eiv_model, fit_eiv, log_p_prior
from hybrid_sysid.physics.eiv.fit import fix_samples
from hybrid_sysid.physics.eiv.model import check_noise_ratio
from hybrid_sysid.physics.faults import fix_code
from hybrid_sysid.physics.faults.skew import check_skew_max
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows

PRIOR_KEYS = ("m3_min", "m3_max", "c3", "k3", "seat_spread")
EDGE = 0.05  # in log p: a fit this close to its box's edge ran into it
PRIOR_FLOOR = 1e-4  # added in quadrature to the prior's standard deviations of log p


def _trusted(fit, start: np.ndarray) -> np.ndarray:
    """(n, 1): the likelihood fit converged inside its box, away from its edges, and within a factor 2 of its start.
    On noisy windows of smooth roads the likelihood has spurious minima at the box's edges, with a small se there."""
    lo, hi = np.log(P_LO), np.log(P_HI)
    with np.errstate(invalid="ignore", divide="ignore"):
        theta = np.log(fit.p)
        inside = ((theta > lo + EDGE) & (theta < hi - EDGE)).all(axis=1)
        near = (np.abs(theta - np.log(start)) < np.log(2.0)).all(axis=1)
    return (fit.converged & inside & (near | ~np.isfinite(start).all(axis=1)))[:, None]


def _kept(out, p0: np.ndarray, se0: np.ndarray, guarded: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The fit's (p, se) where it is defined (and, ``guarded``, trusted), the start's elsewhere."""
    ok = np.isfinite(out.p).all(axis=1, keepdims=True)
    if guarded:
        ok &= _trusted(out, p0)
    return np.where(ok, out.p, p0), np.where(ok, out.se, se0)


class ErrorsInVariablesFit:
    """The errors-in-variables ML (or MAP) estimate of (p1, p2) per evaluation window, scored like a network.

    noise_ratio: sigma_body^2 / sigma_seat^2 in [0, 1e6] (0: output error, the body channel taken as exact).
    prior: None (maximum likelihood), or the simulator's draws of the seat as a dict of ``PRIOR_KEYS`` (conf/baseline/
        eiv_map.yaml fills it from the data and car sections): the fit is then the MAP estimate with the Gaussian in
        log p of those draws' moments, and sigma from the likelihood fit's residual.
    low_hz, high_hz, taps: the band-pass of the least-squares start (the ls_bandpass baseline's band).
    fix: "none", or the recording fault fitted with p ("gain", "skew", "hardening"; physics.eiv); ``skew_max``:
        the largest time offset of the body sensor, seconds, that "skew" considers.
    With K windows per recording (evaluation.windows) the K estimates are averaged, as a network's are.
    """

    fit_seconds = fit_cpu_seconds = 0.0  # wall and CPU time spent in predict_split (as LeastSquares')

    def __init__(
        self,
        noise_ratio: float = 1.0,
        prior: dict | None = None,
        dt: float = 0.005,
        low_hz: float = 4.0,
        high_hz: float = 20.0,
        taps: int = 151,
        fix: str = "none",
        skew_max: float = 0.02,
    ):
        self.noise_ratio = check_noise_ratio(noise_ratio)  # physics.eiv's checks, at construction: before any work
        fix_code(fix)  # a registered fix (physics.faults.fixes), else a ConfigError naming fix
        self.fix = fix
        self.skew_max = check_skew_max(skew_max)
        self.fir = bandpass_taps(low_hz, high_hz, taps, dt)  # physics.filters' check of the band first
        self.dt, self.taps = float(dt), int(taps)
        if prior is not None and not isinstance(prior, Mapping):
            bad("prior", prior, f"null, or a dict with {', '.join(PRIOR_KEYS)}")
        self.prior_settings = None if prior is None else dict(prior)
        self.prior = None
        if prior is not None:
            missing = [k for k in PRIOR_KEYS if k not in prior]
            if missing:
                bad("prior", dict(prior), f"a dict with {', '.join(PRIOR_KEYS)} (missing {', '.join(missing)})")
            # a key the prior does not read would be ignored in silence (a misspelt seat_spread: no spread)
            for k in prior:
                if k not in PRIOR_KEYS:
                    bad(f"prior.{k}", prior[k], f"not a key of the prior, which takes {', '.join(PRIOR_KEYS)}")
            try:
                mean, cov = log_p_prior(*(prior[k] for k in PRIOR_KEYS))
            except ConfigError as exc:  # log_p_prior names its own arguments: under prior, as the config has them
                raise exc.under("prior") from None
            # without a spread of the seat's constants (the paper's data) p1 / p2 = C3 / K3 is fixed and the prior's
            # covariance singular: a floor of 1e-4 on its standard deviations keeps that constraint, as a prior
            self.prior = (mean, cov + PRIOR_FLOOR**2 * np.eye(2))
        self.fit_seconds = self.fit_cpu_seconds = 0.0

    def check_lengths(self, window: int, n_steps: int) -> None:
        """The least-squares start's band-pass must leave enough samples of a window, and the skew fix's edges too
        (the fit would refuse each window only once the data are simulated)."""
        check_filter_fits(self.taps, window, "taps", "data.window")
        code = fix_code(self.fix)
        if code is not None and any(code.eiv_edges(self.skew_max, self.dt)):  # the skew's: its advance's reach
            need = max(fix_samples(self.fix, model, self.dt, self.skew_max) for model in ("discrete", "continuous"))
            if window < need:
                bad(
                    "skew_max",
                    self.skew_max,
                    f"a skew whose fix fits in data.window = {window} samples ({need} needed)",
                )

    def fit_windows(
        self, seat, body, dt: float, measurement: str, guarded: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """(p, se), each (n, 2) float64, of windows (n, W) of seat and body acceleration: the estimate and its relative
        standard error. Where the likelihood fit is not defined, the least-squares start and its standard error
        (with a fix: the least squares with that fix, whose standard error is not known, so infinite, or where that
        is not defined either the plain least squares); NaN p and infinite se where none is.

        ``guarded``: also where the likelihood fit is not to be trusted (``_trusted``): an anchor weighs the fit by
        its se, and a fit run to the edge of its box on a barely informative window comes with a small se."""
        _, p0, se0, out = self._fit(seat, body, dt, measurement)
        return _kept(out, p0, se0, guarded)

    def fit_with_ml(self, seat, body, dt: float, measurement: str):
        """With a prior: the band-passed least squares (physics.seat_fit.SeatFit), the guarded ML fit's (p, se) and
        the MAP fit's (p, se) of the same windows, as ``fit_windows`` gives each, with the likelihood solved once
        (the MAP fit starts from the ML one); last the raw fit (p0, se0, EivFit), from which a Bayes estimate of
        the same windows (baselines.eiv_bayes, ``from_fit``) needs no fit again."""
        if self.prior is None:
            raise ValueError("fit_with_ml needs a prior: the ML fit alone is fit_windows")
        start, p0, se0, out = self._fit(seat, body, dt, measurement)
        return start, _kept(out.ml, p0, se0, guarded=True), _kept(out, p0, se0), (p0, se0, out)

    def _fit(self, seat, body, dt: float, measurement: str):
        """The least-squares start, the likelihood fit's start p0 and its fallback se0, and the EivFit."""
        seat, body = np.asarray(seat, dtype=np.float64), np.asarray(body, dtype=np.float64)
        start = fit_windows(seat, body, dt, measurement, self.fir)
        p0, se0 = start.p, start.se
        if self.fix != "none":
            rel_vel, rel_disp = relative_states(seat, body, dt, measurement)
            fixed = fit_fixed(self.fix, seat, body, rel_vel, rel_disp, dt, measurement, self.fir, self.skew_max)
            defined = np.isfinite(fixed).all(axis=1, keepdims=True)
            p0, se0 = np.where(defined, fixed, p0), np.where(defined, np.inf, se0)
        out = fit_eiv(
            seat,
            body,
            dt,
            noise_ratio=self.noise_ratio,
            model=eiv_model(measurement),
            p0=p0,
            prior=self.prior,
            fix=self.fix,
            skew_max=self.skew_max,
        )
        return start, p0, se0, out

    def fit(self, seat, body, dt: float, measurement: str) -> np.ndarray:
        """(n, 2) estimates of windows (n, W) of seat and body acceleration (``fit_windows``' p)."""
        return self.fit_windows(seat, body, dt, measurement)[0]

    def estimate(self, seat, body, dt: float, measurement: str, window: int, windows: int) -> np.ndarray:
        """(K, 2) estimates of one recording at K evenly spaced windows (model.base.Baseline)."""
        starts = window_starts(len(seat), window, windows)
        seat, body = (np.stack([np.asarray(x, dtype=np.float64)[s : s + window] for s in starts]) for x in (seat, body))
        return self.fit(seat, body, dt, measurement)

    def predict_split(self, dm, split: str, noise_std: float, limit: int | None = None, windows: int = 1):
        """Estimates and truth, float64 (n, 2), one row per recording (model.base.SplitPredictor)."""
        begin, cpu = time.perf_counter(), time.process_time()
        dm.setup()
        self.check_lengths(dm.window, dm.data.n_steps)
        batch = dm.eval_batch(split, noise_std, limit, windows=windows)
        seat, body = (batch["signals"][:, i].numpy().astype(np.float64) for i in (0, 1))
        spec = dm.dataset.spec
        p = self.fit(seat, body, spec.dt, spec.measurement)
        pred = p.reshape(-1, windows, 2).mean(axis=1)
        true = batch["params"].numpy().astype(np.float64).reshape(-1, windows, 2)[:, 0]
        self.fit_seconds += time.perf_counter() - begin
        self.fit_cpu_seconds += time.process_time() - cpu
        return pred, true
