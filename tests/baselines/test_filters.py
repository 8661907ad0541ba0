"""The FIR band-pass: its frequency response, its 'valid' convolution, and the seat equation surviving it."""

import numpy as np
import pytest

from hybrid_sysid.baselines import LeastSquaresFit, fit_p
from hybrid_sysid.physics.filters import bandpass_taps, fir_valid

DT = 0.005  # 200 Hz sampling, Nyquist 100 Hz


@pytest.mark.parametrize("low, high, taps", [(4.0, 20.0, 151), (2.0, 30.0, 401), (10.0, 60.0, 101)])
def test_frequency_response_passes_the_band_and_stops_dc_and_nyquist(low, high, taps):
    h = bandpass_taps(low, high, taps, DT)
    assert h.shape == (taps,) and h.dtype == np.float64
    np.testing.assert_array_equal(h, h[::-1])  # symmetric: zero phase once its delay is cut off
    n = 1 << 14
    gain = np.abs(np.fft.rfft(h, n))
    f = np.fft.rfftfreq(n, DT)
    half = 2.75 / (taps * DT)  # half of a Blackman window's transition width, Hz
    passband = (f >= low + half) & (f <= high - half)
    assert passband.sum() > 10
    np.testing.assert_allclose(gain[passband], 1.0, atol=2e-3)
    assert gain[0] < 1e-12  # exactly zero DC gain by construction
    assert gain[-1] < 1e-4  # Nyquist
    stop = (f <= max(low - half, 0.0)) | (f >= high + half)
    assert gain[stop].max() < 2e-3
    # -6 dB (half amplitude) at the nominal edges
    np.testing.assert_allclose(np.interp([low, high], f, gain), 0.5, atol=0.01)


def test_fir_valid_equals_numpy_convolve_row_by_row():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((7, 300))
    h = rng.standard_normal(31)
    out = fir_valid(x, h)
    assert out.shape == (7, 270)
    for row, got in zip(x, out):
        np.testing.assert_allclose(got, np.convolve(row, h, mode="valid"), rtol=0, atol=1e-12)
    with pytest.raises(
        ValueError, match="taps = 31 is not allowed: must be at most the 20 samples of the signal it filters"
    ):
        fir_valid(x[:, :20], h)


def test_the_seat_equation_survives_the_filter(clean_recordings):
    """Linear and time invariant: filtering z'', rel_vel and rel_disp alike keeps p exact (whole series and a
    window cut after integrating from t0)."""
    r = clean_recordings
    h = bandpass_taps(4.0, 20.0, 151, DT)
    for sl in (slice(None), slice(300, 800)):
        p = fit_p(r["seat"][:, sl], r["rel_vel"][:, sl], r["rel_disp"][:, sl], h)
        np.testing.assert_allclose(p, r["p"], rtol=1e-6)
    # a band with no resonance in it still gives p back: the relation holds at every frequency
    p = fit_p(r["seat"], r["rel_vel"], r["rel_disp"], bandpass_taps(15.0, 40.0, 101, DT))
    np.testing.assert_allclose(p, r["p"], rtol=1e-6)


BAD = [
    (dict(high_hz=150), r"^high_hz = 150 is not allowed: must lie in \(low_hz = 4, Nyquist = 100 Hz\)$"),
    (dict(high_hz=3.0), r"^high_hz = 3.0 is not allowed: must lie in \(low_hz = 4, Nyquist = 100 Hz\)$"),
    (dict(low_hz=0), r"^low_hz = 0 is not allowed: must lie in \(0, Nyquist = 100 Hz\)$"),
    (dict(low_hz=-1.5), r"^low_hz = -1\.5 is not allowed: must lie in \(0, Nyquist = 100 Hz\)$"),
    (dict(taps=100), r"^taps = 100 is not allowed: must be an odd integer >= 3"),
    (dict(taps=1), r"^taps = 1 is not allowed: must be an odd integer >= 3"),
    (dict(taps=50.5), r"^taps = 50\.5 is not allowed: must be an odd integer >= 3"),
    (dict(dt=0), r"^dt = 0 is not allowed: must be > 0"),
    (dict(dt=0.001, high_hz=600), r"^high_hz = 600 is not allowed: .*Nyquist = 500 Hz\)$"),
    (dict(span="recording"), r"^span = 'recording' is not allowed: one of window, series$"),
    (dict(filter="lowpass"), r"^filter = 'lowpass' is not allowed: one of none, bandpass$"),
]


@pytest.mark.parametrize("kwargs, match", BAD)
def test_bad_values_raise_one_line_naming_key_value_and_range(kwargs, match):
    with pytest.raises(ValueError, match=match) as info:
        LeastSquaresFit(**{"filter": "bandpass", **kwargs})
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "overrides, match",
    [
        (
            ["baseline=ls_bandpass", "baseline.high_hz=150"],
            r"baseline\.high_hz = 150 is not allowed: must lie in \(low_hz = 4, Nyquist = 100 Hz\)",
        ),
        (
            ["baseline=ls_bandpass", "baseline.span=window", "baseline.taps=495"],
            r"baseline\.taps = 495 is not allowed: must be <= data\.window - 9 = 491",
        ),
        (
            ["baseline=ls_bandpass", "data.n_steps=150", "data.window=100"],
            r"baseline\.taps = 151 is not allowed: must be <= data\.n_steps - 9 = 141",
        ),
        (["baseline=ls_window", "baseline.span=all"], r"baseline\.span = 'all' is not allowed: one of window, series"),
    ],
)
def test_config_validation_reports_the_baselines_errors(make_cfg, overrides, match):
    from hybrid_sysid.config import ConfigError, validate

    with pytest.raises(ConfigError, match=match):
        validate(make_cfg(*overrides))


def test_baseline_configs_are_valid(make_cfg):
    from hybrid_sysid.config import validate

    for model in ("ls_window", "ls_series", "ls_bandpass"):
        for data in ("default", "tiny", "paper"):
            validate(make_cfg(f"baseline={model}", f"data={data}"))
