"""The compiled dataset kernel against the numpy simulator and re-integration it replaces."""

import numpy as np
import pytest

from hybrid_sysid.physics import QuarterCar, fused, relative_states, road_profiles, simulate

pytestmark = pytest.mark.skipif(not fused.available(), reason="numba not installed")


@pytest.mark.parametrize("measurement", ["paper", "consistent"])
def test_fused_kernel_equals_numpy_path(measurement):
    dt = 0.004
    roads = road_profiles(list("ABCDE"), 700, dt, 13.0, rng=11)
    masses = np.array([[50.0, 81.0, 133.0, 200.0]] * 5)
    car = QuarterCar(c3=700.0)
    out64 = tuple(np.empty((20, 700)) for _ in range(4))
    fused.simulate_recordings(roads, np.repeat(np.arange(5), 4), masses.ravel(), dt, car, measurement, out=out64)
    seat, body = simulate(roads[:, None, :], masses, dt, car, measurement)
    ref = (seat, body, *relative_states(seat, body, dt, measurement))
    for got, want in zip(out64, ref):
        np.testing.assert_allclose(got, want.reshape(20, 700), rtol=1e-12, atol=1e-12 * np.abs(want).max())
    out32 = fused.simulate_recordings(roads, np.repeat(np.arange(5), 4), masses.ravel(), dt, car, measurement)
    for got, want in zip(out32, ref):
        assert got.dtype == np.float32
        np.testing.assert_array_equal(got, want.reshape(20, 700).astype(np.float32))


@pytest.mark.parametrize("measurement", ["paper", "consistent"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("n_rec, n_steps", [(7, 300), (37, 261), (32, 8), (1, 5)])
def test_fused_kernel_any_count_length_and_road_order(measurement, dtype, n_rec, n_steps):
    # recordings run in blocks of fused.LANES and tiles of fused.STEPS steps written eight at a time: counts
    # and lengths that leave partial blocks, partial tiles and tails shorter than eight, and roads in any
    # order, must still give each recording its own road and mass, equal to the numpy path op for op
    dt = 0.005
    roads = road_profiles(list("ACE"), n_steps, dt, 15.0, rng=3)
    rng = np.random.default_rng(n_rec)
    road_of = rng.integers(0, 3, size=n_rec)
    m3 = rng.uniform(50.0, 200.0, size=n_rec)
    out = tuple(np.full((n_rec, n_steps), np.nan, dtype=dtype) for _ in range(4))
    fused.simulate_recordings(roads, road_of, m3, dt, QuarterCar(), measurement, out=out)
    seat, body = simulate(roads[road_of], m3, dt, QuarterCar(), measurement)
    for got, want in zip(out, (seat, body, *relative_states(seat, body, dt, measurement))):
        np.testing.assert_array_equal(got, want.astype(dtype))


def test_fused_kernel_rejects_unusable_output_arrays():
    roads = road_profiles(["A"], 40, 0.005, 15.0, rng=3)
    good = [np.empty((2, 40), np.float32) for _ in range(4)]
    for bad in (np.empty((2, 40), np.float64), np.empty((2, 39), np.float32), np.empty((2, 80), np.float32)[:, ::2]):
        with pytest.raises(ValueError, match="out must be four C-contiguous float32 or float64 arrays"):
            fused.simulate_recordings(roads, [0, 0], [60.0, 90.0], 0.005, out=[*good[:3], bad])
