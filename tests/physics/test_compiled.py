"""The compiled dataset kernel against the numpy simulator and re-integration it replaces."""

import subprocess
import sys

import numpy as np
import pytest

from hybrid_sysid.physics import QuarterCar, relative_states, road_profiles, simulate
from hybrid_sysid.physics.compiled import LANES, simulate_recordings


@pytest.mark.parametrize("measurement", ["paper", "consistent"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("n_rec, n_steps", [(37, 261), (2 * LANES, 300), (1, 5)])
def test_kernel_equals_the_numpy_path(measurement, dtype, n_rec, n_steps):
    # recordings run in blocks of LANES: 37 (prime) leaves a partial last block for any block size; roads come
    # in any order, and every recording must get its own road and mass, equal to the numpy path op for op
    dt = 0.005
    roads = road_profiles(list("ACE"), n_steps, dt, 15.0, rng=3)
    rng = np.random.default_rng(n_rec)
    road_of = rng.integers(0, 3, size=n_rec)
    m3 = rng.uniform(50.0, 200.0, size=n_rec)
    car = QuarterCar(c3=700.0, k2=150000.0)
    out = tuple(np.full((n_rec, n_steps), np.nan, dtype=dtype) for _ in range(4))
    simulate_recordings(roads, road_of, m3, dt, car, measurement, out=out)
    seat, body = simulate(roads[road_of], m3, dt, car, measurement)
    for got, want in zip(out, (seat, body, *relative_states(seat, body, dt, measurement))):
        np.testing.assert_array_equal(got, want.astype(dtype))


def test_by_default_float32_and_the_numpy_paths_measurement():
    roads = road_profiles(["C"], 200, 0.005, 15.0, rng=4)
    got = simulate_recordings(roads, [0, 0, 0], [60.0, 120.0, 190.0], 0.005)
    seat, body = simulate(roads[[0, 0, 0]], [60.0, 120.0, 190.0], 0.005)
    for a, b in zip(got, (seat, body, *relative_states(seat, body, 0.005))):
        assert a.dtype == np.float32
        np.testing.assert_array_equal(a, b.astype(np.float32))


def test_kernel_rejects_unusable_output_arrays_and_measurements():
    roads = road_profiles(["A"], 40, 0.005, 15.0, rng=3)
    good = [np.empty((2, 40), np.float32) for _ in range(4)]
    for bad in (np.empty((2, 40), np.float64), np.empty((2, 39), np.float32), np.empty((2, 80), np.float32)[:, ::2]):
        with pytest.raises(ValueError, match="out = .* is not allowed: four C-contiguous float32 or float64 arrays"):
            simulate_recordings(roads, [0, 0], [60.0, 90.0], 0.005, out=[*good[:3], bad])
    with pytest.raises(ValueError, match="measurement = 'eq12' is not allowed: one of paper, consistent"):
        simulate_recordings(roads, [0, 0], [60.0, 90.0], 0.005, measurement="eq12")


@pytest.mark.integration
def test_the_physics_package_does_not_load_the_compiler():
    # a new process: what an import loads, in an interpreter that has loaded nothing yet
    code = "import sys, hybrid_sysid.physics; print(sorted(m for m in ('numba', 'llvmlite') if m in sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "[]"


@pytest.mark.parametrize("measurement", ["paper", "consistent"])
def test_per_recording_seat_constants_reach_the_seat_and_the_body(measurement):
    # C3 and K3 act on the seat (eq. 7) and on the body (eq. 8): each recording as the numpy simulator of a car
    # with that recording's seat alone
    roads = road_profiles(list("BD"), 250, 0.005, 15.0, rng=5)
    road_of, m3 = [0, 1, 1], [70.0, 120.0, 180.0]
    c3, k3 = np.array([500.0, 615.0, 760.0]), np.array([75000.0, 120000.0, 98935.0])
    got = simulate_recordings(roads, road_of, m3, 0.005, QuarterCar(), measurement, c3=c3, k3=k3)
    for i in range(3):
        seat, body = simulate(roads[road_of[i]], m3[i], 0.005, QuarterCar(c3=c3[i], k3=k3[i]), measurement)
        np.testing.assert_array_equal(got[0][i], seat.astype(np.float32))
        np.testing.assert_array_equal(got[1][i], body.astype(np.float32))
