"""car.seat_hardening: a seat spring F = K3 (d + kappa d^3), against solve_ivp of the nonlinear quarter car, the
compiled kernel against the numpy step, the seat equation it records, the bias it gives a linear fit, and where it
is refused."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.dataset import generate_dataset
from hybrid_sysid.physics import QuarterCar, continuous_recordings, relative_states, simulate
from hybrid_sysid.physics.compiled import simulate_recordings
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows

KAPPA = 3.0e5  # 1/m^2: strong, so that the nonlinearity shows far above the scheme's error
M3 = 80.0
AMP, FREQ, PHASE = np.array([0.03, 0.012, 0.004]), np.array([1.3, 3.7, 7.9]), np.array([0.3, 1.1, 2.0])
SPAN = 1.5  # s


def road(t):
    return (AMP[:, None] * np.sin(2 * np.pi * FREQ[:, None] * np.atleast_1d(t)[None] + PHASE[:, None])).sum(axis=0)


def reference(kappa: float):
    """z - y of the quarter car with the hardening seat spring, written from the forces, by solve_ivp: a function
    of time (its dense output)."""
    car = QuarterCar()

    def rhs(t, s):
        w, v, u, z, y, x = s
        d = z - y
        spring = car.k3 * (d + kappa * d**3)
        seat = -car.c3 * (w - v) - spring
        suspension = -car.c2 * (v - u) - car.k2 * (y - x)
        tyre = -car.k1 * (x - road(t)[0])
        return [seat / M3, (-seat + suspension) / car.m2, (-suspension + tyre) / car.m1, w, v, u]

    sol = solve_ivp(rhs, (0, SPAN), np.zeros(6), method="DOP853", dense_output=True, rtol=1e-11, atol=1e-14)
    return lambda t: sol.sol(t)[3] - sol.sol(t)[4]


def simulated(kappa: float, dt: float) -> np.ndarray:
    """z_k - y_k by the simulator's step (the consistent recording re-integrates to its states)."""
    n = int(round(SPAN / dt))
    out = tuple(np.empty((1, n)) for _ in range(4))
    car = QuarterCar(seat_hardening=kappa)
    simulate_recordings(road(dt * np.arange(n))[None], [0], [M3], dt, car, "consistent", out)
    return out[3][0]


def test_the_hardening_seat_converges_to_solve_ivp_of_the_nonlinear_equations():
    # symplectic Euler is first order: halving dt halves the error against the nonlinear solution, whose
    # difference from the linear car's is far larger than the error left at the finest step
    nonlinear, linear = reference(KAPPA), reference(0.0)
    errors = []
    for dt in (4e-4, 2e-4, 1e-4):
        exact = nonlinear(dt * np.arange(int(round(SPAN / dt))))
        errors.append(np.max(np.abs(simulated(KAPPA, dt) - exact)) / np.max(np.abs(exact)))
    assert errors[0] / errors[1] == pytest.approx(2, rel=0.1)
    assert errors[1] / errors[2] == pytest.approx(2, rel=0.1)
    t = 1e-4 * np.arange(int(round(SPAN / 1e-4)))
    mismatch = np.max(np.abs(linear(t) - nonlinear(t))) / np.max(np.abs(nonlinear(t)))
    assert errors[2] < 0.005 and mismatch > 0.1  # measured: 0.23% and 23%


def test_the_compiled_kernel_equals_the_numpy_step_with_hardening():
    rng = np.random.default_rng(0)
    roads = 0.02 * np.cumsum(rng.standard_normal((2, 400)), axis=1) / 20
    car = QuarterCar(seat_hardening=KAPPA)
    for measurement in ("consistent", "paper"):
        seat, body = simulate(roads[:, None, :], np.array([[60.0, 150.0]] * 2), 0.005, car, measurement)
        out = tuple(np.empty((4, 400)) for _ in range(4))
        simulate_recordings(roads, [0, 0, 1, 1], [60.0, 150.0] * 2, 0.005, car, measurement, out)
        np.testing.assert_array_equal(out[0], seat.reshape(4, -1))
        np.testing.assert_array_equal(out[1], body.reshape(4, -1))
        rel = relative_states(seat.reshape(4, -1), body.reshape(4, -1), 0.005, measurement)
        np.testing.assert_array_equal(out[2], rel[0])
        np.testing.assert_array_equal(out[3], rel[1])


@pytest.fixture(scope="module")
def hardening():
    spec = DatasetSpec(n_roads=2, n_masses=4, road_classes=("E",), car=QuarterCar(seat_hardening=35000.0))
    return generate_dataset(spec)


def test_the_recording_obeys_the_nonlinear_seat_equation(hardening):
    # z'' = -p1 rel_vel - p2 (rel_disp + kappa rel_disp^3) to float32 rounding; the linear equation misses by more
    ds = hardening
    p1, p2 = ds.params[:, :1], ds.params[:, 1:]
    vel, disp = ds.rel_vel.astype(float), ds.rel_disp.astype(float)
    scale = np.abs(ds.seat_acc).max()
    nonlinear = ds.seat_acc + p1 * vel + p2 * (disp + 35000.0 * disp**3)
    linear = ds.seat_acc + p1 * vel + p2 * disp
    assert np.max(np.abs(nonlinear)) < 1e-5 * scale
    assert np.max(np.abs(linear)) > 1e-2 * scale


def test_a_linear_fit_reads_p2_too_high_on_a_hardening_seat(hardening):
    fir = bandpass_taps(4.0, 20.0, 151, 0.005)
    fit = fit_windows(hardening.seat_acc[:, :500], hardening.body_acc[:, :500], 0.005, "consistent", fir)
    rel = fit.p[:, 1] / hardening.params[:, 1] - 1
    assert np.all(rel > 0.01) and np.mean(rel) > 0.03  # stiffer at amplitude: a larger p2
    linear = generate_dataset(DatasetSpec(n_roads=2, n_masses=4, road_classes=("E",)))
    clean = fit_windows(linear.seat_acc[:, :500], linear.body_acc[:, :500], 0.005, "consistent", fir)
    assert np.max(np.abs(clean.p[:, 1] / linear.params[:, 1] - 1)) < 1e-4


def test_a_linear_spring_keeps_the_cache_key_and_0_is_allowed():
    assert DatasetSpec(car=QuarterCar(seat_hardening=0.0)).key() == DatasetSpec().key()
    assert DatasetSpec(car=QuarterCar(seat_hardening=1e4)).key() != DatasetSpec().key()
    DatasetSpec(n_roads=2, n_masses=1, n_steps=10).validate()


@pytest.mark.parametrize(
    "spec, words",
    [
        (DatasetSpec(car=QuarterCar(seat_hardening=-1.0)), "must lie in [0, "),
        (DatasetSpec(car=QuarterCar(seat_hardening=float("inf"))), "must lie in [0, "),
        (DatasetSpec(measurement="continuous", car=QuarterCar(seat_hardening=1e4)), "continuous"),
    ],
)
def test_refused_where_it_cannot_apply(spec, words):
    with pytest.raises(ConfigError) as info:
        spec.validate()
    assert info.value.key == "car.seat_hardening" and words in str(info.value) and "\n" not in str(info.value)


def test_the_exact_solution_refuses_a_hardening_car():
    with pytest.raises(ConfigError, match="car.seat_hardening"):
        continuous_recordings(
            np.ones((1, 2)),
            np.zeros((1, 2)),
            np.array([1.0, 2.0]),
            [0],
            [80.0],
            10,
            0.005,
            QuarterCar(seat_hardening=1.0),
        )
