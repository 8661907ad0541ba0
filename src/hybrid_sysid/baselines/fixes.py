"""The classical fix of each recording fault (docs/faults.md): one more parameter in the band-passed least-squares
fit of the seat equation, so the fault is estimated with p instead of biasing it. Plain numpy, per window.

Each fix's code lies in its fault's file (``physics.faults``: ``Fix.least_squares``), found by its name in the
registry: "gain" (physics.faults.gain), "skew" (physics.faults.skew) and "hardening" (physics.faults.hardening),
and a registered fault's own. The names below stay importable from here.
"""

from __future__ import annotations

from hybrid_sysid.physics.faults.fix import lstsq_columns
from hybrid_sysid.physics.faults.gain import fit_gain
from hybrid_sysid.physics.faults.hardening import detrend, fit_hardening
from hybrid_sysid.physics.faults.registry import fix_code
from hybrid_sysid.physics.faults.skew import delayed_copies, fit_skew

__all__ = ["delayed_copies", "detrend", "fit_fixed", "fit_gain", "fit_hardening", "fit_skew", "lstsq_columns"]


def fit_fixed(fix: str, seat, body, rel_vel, rel_disp, dt: float, measurement: str, fir, skew_max: float):
    """p (n, 2) of windows (n, W) by the fit with ``fix``'s extra parameter (``rel_vel``, ``rel_disp``: the
    regressors integrated from t0 and cropped, as the data module serves them)."""
    return fix_code(fix).least_squares(seat, body, rel_vel, rel_disp, dt, measurement, fir, skew_max)
