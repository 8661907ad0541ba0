"""model=anchored with a prior (model.net.prior, conf/model/anchored.yaml): p_net is the window's MAP fit times a
learned factor, gated against the likelihood fit as before; trunk=false reads the fits' statistics alone.
References: ErrorsInVariablesFit's ML and MAP fits of the same windows, computed here, and the gate's formula."""

import numpy as np
import pytest
import torch
from test_anchored import DT, P_MAX, P_MIN, W, windows

from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.model.anchored import AnchoredCNN

PRIOR = {"m3_min": 50, "m3_max": 200, "c3": 615.0, "k3": 98935.0, "seat_spread": 0.3}


def net(seed=0, **kwargs):
    torch.manual_seed(seed)
    return AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="eiv", prior=PRIOR, **kwargs).eval()


@pytest.mark.parametrize("trunk", [True, False])
def test_before_training_the_output_gates_the_likelihood_fit_against_the_map_fit(trunk):
    """The head's last layer starts at zero: delta = 0, so p_net is the MAP fit, and tau^2 = tau_min tau_max."""
    acc, truth = windows(noise=0.03, n=16)
    x = acc.astype(np.float64)
    with torch.no_grad():
        out = net(trunk=trunk)(torch.from_numpy(acc)).double().numpy()
    p_ml, se = ErrorsInVariablesFit(dt=DT).fit_windows(x[:, 0], x[:, 1], DT, "consistent", guarded=True)
    p_map = ErrorsInVariablesFit(dt=DT, prior=PRIOR).fit_windows(x[:, 0], x[:, 1], DT, "consistent")[0]
    w = 1e-3 / (1e-3 + se**2)
    np.testing.assert_allclose(out, w * p_ml + (1 - w) * p_map, rtol=2e-5)  # float32 output
    assert np.abs(out / p_ml - 1).max() > 1e-3  # the MAP fit moved some of them


def test_clean_windows_give_the_true_p_with_a_prior_whatever_the_head():
    acc, truth = windows()
    model = net(trunk=False)
    with torch.no_grad():
        model.head[-1].bias.copy_(torch.tensor([-20.0, 20.0, -20.0, -20.0]))  # delta at its ends, tau at its floor
        p = model(torch.from_numpy(acc)).double().numpy()
    assert np.abs(p / truth - 1).max() <= 1e-4


def test_the_learned_factor_is_bounded_and_the_gradient_finite_where_no_fit_is_defined():
    acc, _ = windows(noise=0.1, n=6)
    signals = torch.cat([torch.from_numpy(acc), torch.zeros(2, 2, W)])  # two parked windows: no fit at all
    model = net(trunk=False).train()
    with torch.no_grad():
        model.head[-1].bias.copy_(torch.tensor([50.0, -50.0, -20.0, -20.0]))
    p = model(signals)
    p.sum().backward()
    assert all(torch.isfinite(q.grad).all() for q in model.parameters() if q.grad is not None)
    x = acc.astype(np.float64)
    p_map = ErrorsInVariablesFit(dt=DT, prior=PRIOR).fit_windows(x[:, 0], x[:, 1], DT, "consistent")[0]
    ratio = p[:6].detach().double().numpy() / p_map
    assert ratio.max() <= 2.0 * (1 + 1e-5) and ratio.min() >= 0.5 * (1 - 1e-5)  # MAX_FACTOR, either way
    assert torch.isfinite(p[6:]).all()


def test_without_the_trunk_the_network_has_no_convolution():
    model = net(trunk=False)
    assert not any(isinstance(m, torch.nn.Conv1d) for m in model.modules())
    assert sum(q.numel() for q in model.parameters()) < sum(q.numel() for q in net(trunk=True).parameters()) / 2


@pytest.mark.parametrize(("arguments", "key"), [({"trunk": "no"}, "trunk"), ({"prior": {"m3_min": 50}}, "prior")])
def test_bad_values_name_their_key(arguments, key):
    kwargs = {"prior": PRIOR, **arguments}
    with pytest.raises(ConfigError) as info:
        AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="eiv", **kwargs)
    assert info.value.key == key


def test_the_config_gives_the_network_the_map_baselines_prior(make_cfg):
    from hybrid_sysid.training.build import build_model

    for spread in (0.0, 0.3):
        cfg = make_cfg("model=anchored", f"data.seat_spread={spread}")
        d = cfg.data
        settings = {"m3_min": d.m3_min, "m3_max": d.m3_max, "c3": cfg.car.c3, "k3": cfg.car.k3, "seat_spread": spread}
        assert build_model(cfg).net.map.prior_settings == settings
