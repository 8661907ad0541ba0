"""The hybrid objective's least-squares target (objective.target, objective=label_free): each window's p_ls from
the residual's own regressors, then the labelled objective's L1 to it. References: numpy's least squares, the
simulator's true p, and the plain residual's conditioning measured in the same test."""

import numpy as np
import pytest
import torch

from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.model.objectives import HybridObjective, least_squares_target
from hybrid_sysid.physics.filters import bandpass_taps

BAND = {"low_hz": 4.0, "high_hz": 20.0, "taps": 151}
# seat constants drawn per recording (seat_spread), as where labels are missing; data=default's dt and window
SPEC = DatasetSpec(n_roads=10, n_masses=4, n_steps=1200, seed=3, seat_spread=0.3)
SCALE = [8.0, 1200.0]


@pytest.fixture(scope="module")
def batch():
    dm = QuarterCarDataModule(
        SPEC, window=500, seed=0, fir=bandpass_taps(4.0, 20.0, 151, SPEC.dt), train_fraction=0.5, val_fraction=0.2
    )
    dm.setup()
    return dm.eval_batch("train", 0.0)


@pytest.mark.parametrize("filtered", [False, True])
def test_on_clean_consistent_windows_the_target_is_the_true_p(batch, filtered):
    keys = ("seat_f", "rel_vel_f", "rel_disp_f") if filtered else ("signals", "rel_vel", "rel_disp")
    seat, vel, disp = (batch[k][:, 0] if k == "signals" else batch[k] for k in keys)
    p_ls, _ = least_squares_target(seat, vel, disp)
    # numpy's least squares on the same float32 signals, window by window
    a = [np.stack([-v, -d], 1).astype(np.float64) for v, d in zip(vel.numpy(), disp.numpy())]
    ref = np.array([np.linalg.lstsq(m, y.astype(np.float64), rcond=None)[0] for m, y in zip(a, seat.numpy())])
    np.testing.assert_allclose(p_ls.numpy(), ref, rtol=1e-6)
    # and the simulator's truth: only the float32 rounding of the stored signals is left (measured: 8e-8 worst)
    true = batch["params"].numpy().astype(np.float64)
    assert np.abs(p_ls.numpy() / true - 1).max() < 1e-4


def test_a_relative_error_costs_alike_on_both_parameters(batch):
    true = batch["params"]

    def ratio(obj):
        """What a 10% error in p2 costs against the same error in p1."""
        cost = [obj(true * torch.tensor(f), batch).item() - obj(true, batch).item() for f in ([1.1, 1.0], [1.0, 1.1])]
        return cost[1] / cost[0]

    # measured on these 16 windows: least_squares 0.94, whitened 0.88; the residual itself 129, band-passed 17
    for target in ("least_squares", "whitened"):
        obj = HybridObjective(filter=BAND, dt=SPEC.dt, target=target, p_scale=SCALE)
        assert 1 / 3 < ratio(obj) < 3, target
    assert ratio(HybridObjective()) > 10  # the residual itself: p1 far cheaper to get wrong
    assert ratio(HybridObjective(filter=BAND, dt=SPEC.dt)) > 10  # band-passed too


def test_the_target_needs_no_labels_and_bad_settings_are_named():
    obj = HybridObjective(target="least_squares", p_scale=SCALE)
    assert obj.uses_labels is False
    with pytest.raises(ValueError, match=r"^target = 'x' is not allowed: one of residual, least_squares"):
        HybridObjective(target="x", p_scale=SCALE)
    with pytest.raises(ValueError, match=r"^p_scale is missing"):
        HybridObjective(target="least_squares")
    with pytest.raises(ValueError, match=r"^weighting = 'eiv' is not allowed: none with target"):
        HybridObjective(target="least_squares", p_scale=SCALE, filter=BAND, dt=SPEC.dt, weighting="eiv")


def test_the_loss_is_the_l1_to_the_target_in_units_of_p_scale(batch):
    obj = HybridObjective(filter=BAND, dt=SPEC.dt, target="least_squares", p_scale=SCALE)
    p_ls, _ = least_squares_target(batch["seat_f"], batch["rel_vel_f"], batch["rel_disp_f"])
    pred = batch["params"].double() * torch.tensor([1.05, 0.97], dtype=torch.float64)
    expected = ((pred - p_ls).abs() / torch.tensor(SCALE, dtype=torch.float64)).sum(dim=1).mean()
    assert obj(pred.float(), batch).item() == pytest.approx(expected.item(), rel=1e-5)
