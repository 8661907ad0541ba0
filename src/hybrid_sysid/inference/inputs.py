"""Recordings as the estimator takes them: seat and body accelerations in m/s^2 coerced to float64 pairs, every
value checked (finite, within float32's range, which the network reads). Bad input raises InputError, one line
naming the item, the value and what is allowed."""

from __future__ import annotations

import numpy as np

from hybrid_sysid.core.checks import InputError, Shown  # InputError: core's, so data.readers raises it too

FLOAT32_MAX = float(np.finfo(np.float32).max)  # the network reads float32: larger magnitudes become inf


def check_windows(windows) -> int:
    """K, the windows averaged per recording: an integer >= 1 (the estimator's check, hybrid-sysid-predict's too);
    returns it."""
    if isinstance(windows, bool) or not isinstance(windows, (int, np.integer)) or windows < 1:
        raise InputError("windows", windows, "an integer >= 1")
    return int(windows)


class EstimateWarning(UserWarning):
    """An estimate not to trust (a flag of docs/predict.md); the message says which recordings and why."""


def recordings(seat_acc, body_acc) -> list[tuple[np.ndarray, np.ndarray]]:
    """(seat, body) float64 1-D pairs, one per recording, with equal lengths checked. seat_acc, body_acc: 1-D (one
    recording), 2-D (recordings, steps) or a list of 1-D arrays (recordings of different lengths)."""
    seat, body = _split("seat_acc", seat_acc), _split("body_acc", body_acc)
    if len(seat) != len(body):
        raise InputError("body_acc", Shown(f"{len(body)} recordings"), f"as many as seat_acc holds, {len(seat)}")
    for i, (s, b) in enumerate(zip(seat, body)):
        if s.shape != b.shape or s.ndim != 1:
            raise InputError(
                f"recording {i}", Shown(f"shapes {s.shape} and {b.shape}"), "two 1-D arrays of one length (seat, body)"
            )
    return list(zip(seat, body))


def _real(name, x):
    """x unchanged; bool and complex arrays would lose what they mean when read as float64."""
    if np.ma.is_masked(x):  # np.asarray keeps the values under the mask: a gap would be read as data
        raise InputError(name, Shown("a masked array with masked values"), "real numbers in m/s^2, none masked")
    dtype = np.asarray(x).dtype
    if dtype.kind in "bc":
        raise InputError(
            name, Shown(f"dtype {dtype}"), "real numbers in m/s^2 (a float or integer array, not bool or complex)"
        )
    return x


def _split(name, x) -> list[np.ndarray]:
    try:
        if isinstance(x, (list, tuple)) and x and np.ndim(x[0]) == 1:
            return [np.asarray(_real(f"{name}[{i}]", r), dtype=np.float64) for i, r in enumerate(x)]
        x = np.asarray(_real(name, x), dtype=np.float64)
    except InputError:
        raise
    except (TypeError, ValueError) as exc:
        raise InputError(name, allowed=f"float arrays in m/s^2 ({exc})") from None
    if x.ndim not in (1, 2) or x.size == 0:
        raise InputError(
            name,
            Shown(f"shape {x.shape}"),
            "1-D (one recording), 2-D (recordings, steps) or a list of 1-D arrays, not empty",
        )
    return [x] if x.ndim == 1 else list(x)


def check_values(channel: str, x: np.ndarray, name) -> None:
    """Every value finite and within float32's range, which the network reads (beyond it: inf, then NaN)."""
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise InputError(f"{channel} of recording {name!r} at step {bad[0]}", float(x[bad[0]]), "finite values")
    big = np.flatnonzero(np.abs(x) > FLOAT32_MAX)
    if big.size:
        raise InputError(
            f"{channel} of recording {name!r} at step {big[0]}",
            float(x[big[0]]),
            f"magnitudes up to {FLOAT32_MAX:g}, float32's range, in which the network reads it",
        )


# a magnitude (m/s^2) below which a non-finite estimate is no overflow: squared, it stays far inside float32
OVERFLOW = 1e15


def check_estimates(estimates: np.ndarray, names: list, stacked: list[np.ndarray]) -> None:
    """Estimates (recordings, K, 2) all finite: values inside float32's range may still overflow the network's
    float32 arithmetic, which then returns NaN or inf rather than an estimate."""
    for name, e, signals in zip(names, estimates, stacked):
        if not np.isfinite(e).all():
            channel = ("seat_acc", "body_acc")[int(np.argmax(np.abs(signals).max(axis=1)))]
            got = f"the estimate is p1 = {e[:, 0].mean():g}, p2 = {e[:, 1].mean():g}"
            if np.abs(signals).max() <= OVERFLOW:  # a constant recording gives an anchored fit 0 / 0, say
                raise InputError(
                    f"recording {name!r}",
                    allowed=f"a recording with the motion the network reads ({got}: a constant or zero recording, "
                    "or one whose seat and body do not move independently?)",
                )
            raise InputError(
                f"recording {name!r}",
                allowed=f"accelerations of the magnitude the run was trained on (its values, up to "
                f"{np.abs(signals).max():g} m/s^2 in {channel}, overflow the network's float32 arithmetic: {got})",
            )
