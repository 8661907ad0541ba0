"""The prior of log p that the data's draws of the seat make, for the MAP fit (fit_eiv's ``prior``)."""

from __future__ import annotations

import numpy as np

from hybrid_sysid.core.checks import bad, check_int, check_number, check_positive


def log_p_prior(m3_min, m3_max, c3, k3, seat_spread, n: int = 200000, seed=0):
    """(mean (2,), cov (2, 2)) of log p = log(c3 / m3, k3 / m3) by Monte Carlo over the data's draws: m3 an
    integer uniform in [m3_min, m3_max], C3 = c3 U(1 - s, 1 + s) and K3 = k3 U(1 - s, 1 + s), s = seat_spread."""
    m3_min, m3_max, spread = check_seat_draws(m3_min, m3_max, seat_spread)
    c3, k3 = check_positive("c3", c3), check_positive("k3", k3)
    n = check_int("n", n, 2)
    rng = np.random.default_rng(seed)
    m3 = rng.integers(m3_min, m3_max + 1, size=n).astype(float)
    log_p = np.stack(
        [
            np.log(c3 * rng.uniform(1.0 - spread, 1.0 + spread, size=n) / m3),
            np.log(k3 * rng.uniform(1.0 - spread, 1.0 + spread, size=n) / m3),
        ],
        axis=1,
    )
    return log_p.mean(axis=0), np.cov(log_p, rowvar=False)


def check_seat_draws(m3_min, m3_max, seat_spread) -> tuple[int, int, float]:
    """The one range check of the simulator's draws of the seat (data.spec calls it too): whole masses in kg,
    m3_min >= 1 and m3_max >= m3_min (the dataset draws integers in [m3_min, m3_max]), and 0 <= seat_spread < 1."""
    m3_min = check_int("m3_min", m3_min, 1)
    if not (isinstance(m3_max, (int, float)) and m3_max >= m3_min):
        bad("m3_max", m3_max, f"empty mass range: must be >= m3_min = {m3_min}")
    m3_max = check_int("m3_max", m3_max, m3_min)
    unit = "a fraction of car.c3 and car.k3"
    return m3_min, m3_max, check_number("seat_spread", seat_spread, 0.0, 1.0, high_open=True, unit=unit)
