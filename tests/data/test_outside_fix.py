"""objective=cross_segment's "eiv" target under a recording fault (data/outside.py, ``fix``): the likelihood fit with
the fault's fix over the longer outside segment. References: the dataset's true p on clean faulted recordings,
where the fix is exact and the plain target is biased; physics.eiv's own fixed fit of the same samples."""

import numpy as np
import pytest

from hybrid_sysid.baselines.fixes import fit_fixed
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.dataset import generate_dataset
from hybrid_sysid.data.outside import SKEW_MAX, OutsideFit
from hybrid_sysid.physics import QuarterCar, relative_states
from hybrid_sysid.physics.eiv import fit_eiv
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.sensors import SensorFaults

DT, N, W = 0.005, 1200, 500
M = N - W
FIR = bandpass_taps(4.0, 20.0, 151, DT)
FAULTS = {  # the fault presets' settings (conf/fault) and the fix ${fault_fix:} names for each
    "skew": dict(sensor=SensorFaults(skew_max=0.01)),
    "gain": dict(sensor=SensorFaults(gain_spread=0.03)),
    "hardening": dict(car=QuarterCar(seat_hardening=35000.0)),
}
# a window at either end, next to either end, in the middle and off it both ways
STARTS = np.array([0, M, 1, M - 1, 350, 349, 351, 120, 580, 200, 500, 40])


@pytest.fixture(scope="module", params=sorted(FAULTS))
def faulted(request):
    spec = DatasetSpec(n_roads=4, n_masses=3, n_steps=N, seed=2, seat_spread=0.3, **FAULTS[request.param])
    return request.param, generate_dataset(spec)


def test_clean_faulted_recordings_give_the_true_p_where_the_plain_target_is_biased(faulted):
    fix, ds = faulted
    rows, truth = np.arange(len(STARTS)), ds.params[: len(STARTS)].astype(np.float64)
    error = {}
    for name in ("none", fix):
        out = OutsideFit(ds.seat_acc, ds.body_acc, DT, ds.spec.measurement, W, FIR, "eiv", fix=name).fit(rows, STARTS)
        error[name] = np.abs(out["p_out"].numpy() / truth - 1)
    # float32 channels: the fixed fit is exact to their rounding; the plain fit of the same recordings is not
    assert error[fix].max() < 1e-4, error[fix].max(axis=0)
    assert error["none"].mean(axis=0).max() > 20 * max(error[fix].mean(axis=0).max(), 1e-6)


def test_the_target_is_the_fixed_fit_of_the_longer_segment_nearest_the_window(faulted):
    fix, ds = faulted
    rng = np.random.default_rng(0)
    rows = np.arange(len(STARTS))
    normals = rng.standard_normal((len(rows), 2, N))
    out = OutsideFit(ds.seat_acc, ds.body_acc, DT, ds.spec.measurement, W, FIR, "eiv", fix=fix)
    got = out.fit(rows, STARTS, 0.003, normals)["p_out"].numpy()
    length = M // 2
    seat = ds.seat_acc[rows].astype(np.float64) + 0.003 * normals[:, 0]
    body = ds.body_acc[rows].astype(np.float64) + 0.003 * normals[:, 1]
    pieces = [slice(s - length, s) if s >= M - s else slice(s + W, s + W + length) for s in STARTS]
    seat = np.stack([seat[i, piece] for i, piece in enumerate(pieces)])
    body = np.stack([body[i, piece] for i, piece in enumerate(pieces)])
    # started where the target starts, from least squares with the same fix: the hardening's alternating fit
    # ends within its tolerance of the minimum, at a point that depends on the start (1e-3 on p2 at this noise)
    p0 = fit_fixed(
        fix, seat, body, *relative_states(seat, body, DT, ds.spec.measurement), DT, ds.spec.measurement, FIR, SKEW_MAX
    )
    want = fit_eiv(seat, body, DT, p0=p0, fix=fix, skew_max=SKEW_MAX)
    np.testing.assert_allclose(got, want.p, rtol=1e-9)


def test_least_squares_target_and_no_fault_keep_the_plain_fit():
    spec = DatasetSpec(n_roads=2, n_masses=2, n_steps=N, seed=1, sensor=SensorFaults(skew_max=0.01))
    ds = generate_dataset(spec)
    rows, starts = np.arange(4), np.array([0, 100, 300, M])
    plain = OutsideFit(ds.seat_acc, ds.body_acc, DT, spec.measurement, W, FIR, "ls").fit(rows, starts)
    fixed = OutsideFit(ds.seat_acc, ds.body_acc, DT, spec.measurement, W, FIR, "ls", fix="skew").fit(rows, starts)
    np.testing.assert_array_equal(fixed["p_out"].numpy(), plain["p_out"].numpy())


def test_recordings_too_short_for_the_fix_are_refused_naming_n_steps():
    spec = DatasetSpec(n_roads=2, n_masses=2, n_steps=700, seed=1, sensor=SensorFaults(skew_max=0.01))
    ds = generate_dataset(spec)
    with pytest.raises(ConfigError, match="n_steps"):
        OutsideFit(ds.seat_acc, ds.body_acc, DT, spec.measurement, W, FIR, "eiv", fix="skew")
    with pytest.raises(ConfigError, match="fix"):
        OutsideFit(ds.seat_acc, ds.body_acc, DT, spec.measurement, W, FIR, "eiv", fix="wobble")
