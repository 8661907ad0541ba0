"""A zero-phase FIR band-pass in plain numpy (windowed sinc, FFT convolution over rows, 'valid' edges).

Why it helps the least-squares fit: the seat equation z'' = -p1 rel_vel - p2 rel_disp is linear and time
invariant, so passing all three signals through the SAME linear filter keeps it exact, while the filter can
drop the frequencies where noise dominates:

- below ~1 Hz the regressors are swamped by integrated sensor noise (white acceleration noise integrates to
  a random walk in rel_vel and to a 1/f^2 drift in rel_disp, growing with time since t0);
- above ~15-20 Hz the seat hardly moves relative to the body (its resonance sqrt(p2) / (2 pi) is 3.5-7 Hz),
  while white sensor noise goes on up to the Nyquist frequency (100 Hz at dt = 5 ms).

The default band (see LeastSquaresFit and conf/baseline/ls_bandpass.yaml) keeps the resonance region.
"""

from __future__ import annotations

import numbers

import numpy as np

from hybrid_sysid.core.checks import ConfigError, bad, check_dt
from hybrid_sysid.core.options import FILTER_KEYS

MAX_TAPS = 100_001  # 500 s at dt = 0.005 s, 800 kB a filter: longer than any window a recording would give


def check_bandpass(low_hz, high_hz, taps, dt) -> None:
    """ConfigError naming the argument, the value and what is allowed."""
    check_dt(dt, allowed="must be > 0 (seconds; the data's time step)")
    nyquist = 0.5 / dt
    if not isinstance(taps, numbers.Integral) or isinstance(taps, bool) or taps < 3 or taps % 2 == 0:
        bad("taps", taps, "must be an odd integer >= 3 (a symmetric, zero-phase FIR)")
    if taps > MAX_TAPS:  # checked before the filter is built: 10^9 taps asked for gigabytes, and the kernel's kill
        bad("taps", taps, f"must be <= {MAX_TAPS} (a band-pass no longer than a window can be)")
    if not isinstance(low_hz, numbers.Real) or not 0 < low_hz < nyquist:
        bad("low_hz", low_hz, f"must lie in (0, Nyquist = {nyquist:g} Hz)")
    if not isinstance(high_hz, numbers.Real) or not low_hz < high_hz < nyquist:
        bad("high_hz", high_hz, f"must lie in (low_hz = {low_hz:g}, Nyquist = {nyquist:g} Hz)")


def _lowpass(fc: float, n: np.ndarray, window: np.ndarray) -> np.ndarray:
    """Windowed-sinc low-pass at fc (cycles per sample), scaled to unit gain at DC."""
    h = 2 * fc * np.sinc(2 * fc * n) * window
    return h / h.sum()


def bandpass_taps(low_hz: float, high_hz: float, taps: int, dt: float) -> np.ndarray:
    """Symmetric (linear-phase; zero-phase once its delay is cut off) band-pass FIR, float64, sum 0.

    The difference of two Blackman-windowed sinc low-passes, each of unit DC gain, so the DC gain is exactly 0.
    Blackman rather than Hamming: its stop band is ~74 dB down instead of ~53 dB, which matters against the
    strong low-frequency drift of integrated noise; its price is a wider transition, ~5.5 / (taps dt) Hz.
    """
    check_bandpass(low_hz, high_hz, taps, dt)
    n = np.arange(taps) - (taps - 1) / 2
    window = np.blackman(taps)
    return _lowpass(high_hz * dt, n, window) - _lowpass(low_hz * dt, n, window)


def filter_taps(filter: dict, dt: float) -> np.ndarray:
    """The band-pass of ``objective.filter`` ({low_hz, high_hz, taps}) at the data's dt: the baseline's FIR."""
    unknown = sorted(set(filter) - set(FILTER_KEYS))
    if unknown:
        bad(
            f"filter.{unknown[0]}",
            filter[unknown[0]],
            f"not a key of a filter, whose keys are {', '.join(FILTER_KEYS)}",
        )
    missing = [k for k in FILTER_KEYS if k not in filter]
    if missing:
        raise ConfigError(f"filter.{missing[0]}", missing=True, allowed=f"give {', '.join(FILTER_KEYS)}")
    try:
        return bandpass_taps(filter["low_hz"], filter["high_hz"], filter["taps"], dt)
    except ConfigError as exc:  # bandpass_taps' check names its argument: under filter, as the config has it
        raise exc.under("filter") from None


def fir_valid(x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Convolve every row of x (..., T) with h (L,) along the last axis, keeping only the T - L + 1 samples
    that see no edge ('valid' mode). By FFT, float64, vectorised over the leading axes."""
    x = np.asarray(x, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    t, taps = x.shape[-1], len(h)
    if taps > t:
        bad("taps", taps, f"must be at most the {t} samples of the signal it filters")
    n = 1 << int(np.ceil(np.log2(t + taps - 1)))  # no circular wrap-around
    y = np.fft.irfft(np.fft.rfft(x, n, axis=-1) * np.fft.rfft(h, n), n, axis=-1)
    return y[..., taps - 1 : t]
