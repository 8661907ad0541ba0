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
def test_fused_kernel_odd_count_and_any_road_order(measurement):
    # recordings run in pairs: an odd count and roads in any order must still give each recording its own
    # road and mass, equal to the numpy path op for op (float64, exactly)
    dt = 0.005
    roads = road_profiles(list("ACE"), 300, dt, 15.0, rng=3)
    road_of = np.array([2, 0, 1, 1, 2, 0, 2])
    m3 = np.array([50.0, 70.0, 90.0, 110.0, 150.0, 180.0, 200.0])
    out = tuple(np.empty((7, 300)) for _ in range(4))
    fused.simulate_recordings(roads, road_of, m3, dt, QuarterCar(), measurement, out=out)
    seat, body = simulate(roads[road_of], m3, dt, QuarterCar(), measurement)
    for got, want in zip(out, (seat, body, *relative_states(seat, body, dt, measurement))):
        np.testing.assert_array_equal(got, want)
