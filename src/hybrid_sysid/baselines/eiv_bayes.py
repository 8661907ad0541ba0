"""The Bayes estimate of each window's (p1, p2) for the mean relative deviation (``baseline=eiv_bayes``): the
errors-in-variables likelihood times the simulator's exact prior of log p, summarised by the median of each
marginal weighted by 1 / p (physics.eiv.posterior). No network, no labels, no training.

It starts from the MAP fit of ``baseline=eiv_map`` (its grid is centred there) and keeps that fit's fallbacks: a
window whose likelihood fit is not defined keeps the band-passed least squares. No fault fix: with one the
likelihood has a third parameter, which the grid would have to span too.
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.baselines.errors_in_variables import PRIOR_KEYS, ErrorsInVariablesFit
from hybrid_sysid.core.checks import ConfigError, bad, check_int
from hybrid_sysid.physics.eiv import eiv_model
from hybrid_sysid.physics.eiv.posterior import POINTS, bayes_fit, check_draws


class ErrorsInVariablesBayes(ErrorsInVariablesFit):
    """The Bayes estimate of (p1, p2) per evaluation window, scored like a network.

    prior: the simulator's draws of the seat, a dict of ``PRIOR_KEYS`` (conf/baseline/eiv_bayes.yaml fills it from
        the data and car sections), with seat_spread > 0: at 0 the prior is a set of points, without a density.
    points: the grid's points per parameter (physics.eiv.posterior.POINTS).
    fix: "none" only. The rest as ErrorsInVariablesFit.
    """

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
        points: int = POINTS,
    ):
        if fix != "none":
            bad("fix", fix, "none (no fault fix here: estimator=eiv_map_fix fits the fault with p)")
        if prior is None:
            bad("prior", prior, f"the simulator's draws, a dict with {', '.join(PRIOR_KEYS)}")
        super().__init__(noise_ratio, prior, dt, low_hz, high_hz, taps, fix, skew_max)
        try:
            check_draws(*(prior[k] for k in PRIOR_KEYS))
        except ConfigError as exc:
            raise exc.under("prior") from None
        self.points = check_int("points", points, 2)

    def fit_windows(
        self, seat, body, dt: float, measurement: str, guarded: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """(p, se), each (n, 2): the Bayes estimate where the MAP fit is defined, with the MAP fit's se (the
        posterior's Laplace width); elsewhere what ``baseline=eiv_map`` keeps there."""
        seat, body = np.asarray(seat, dtype=np.float64), np.asarray(body, dtype=np.float64)
        _, p0, se0, out = self._fit(seat, body, dt, measurement)
        return self.from_fit(seat, body, dt, measurement, p0, se0, out)

    def from_fit(self, seat, body, dt: float, measurement: str, p0, se0, out) -> tuple[np.ndarray, np.ndarray]:
        """``fit_windows`` from a MAP fit already made with this prior (``fit_with_ml``'s last item)."""
        p = bayes_fit(
            seat,
            body,
            dt,
            out,
            self.prior_settings,
            noise_ratio=self.noise_ratio,
            model=eiv_model(measurement),
            points=self.points,
        )
        ok = np.isfinite(p).all(axis=1, keepdims=True)
        return np.where(ok, p, p0), np.where(ok, out.se, se0)
