"""model.net.partner: a second, fit-free estimate on the trunk's features, mixed into the anchored p by a share
that grows with the noise the window's likelihood fit estimates, and trained by the objective on its own.
References: the same network without the partner (its weights copied), the errors-in-variables ML fit's sigma
computed here, and the labelled objective's loss computed by hand."""

import math

import numpy as np
import pytest
import torch
from test_anchored import DT, P_MAX, P_MIN, windows
from test_anchored_prior import PRIOR

from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.model.anchored import AnchoredCNN
from hybrid_sysid.model.module import IdentificationModule
from hybrid_sysid.model.objectives import LabelledObjective


def pair(**kwargs):
    """(with partner, without) sharing every weight the second has. With tau_max 2e-8 the gate's weight of the
    fit is below 1e-12 on noisy windows, so the share is the logistic alone there."""
    torch.manual_seed(0)
    with_partner = AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="eiv", prior=PRIOR, trunk=False, partner=True, **kwargs)
    alone = AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="eiv", prior=PRIOR, trunk=False, **kwargs)
    with torch.no_grad():
        with_partner.head[-1].bias.copy_(torch.tensor([0.3, -0.2, -2.0, 1.0]))
        with_partner.partner_head.bias.copy_(torch.tensor([1.5, -1.0]))
    alone.load_state_dict(with_partner.state_dict(), strict=False)
    return with_partner.eval(), alone.eval()


def sigma_of(acc):
    x = acc.astype(np.float64)
    fit = ErrorsInVariablesFit(prior=PRIOR, dt=DT)
    _, _, _, (_, _, out) = fit.fit_with_ml(x[:, 0], x[:, 1], DT, "consistent")
    return np.sqrt(out.ml.sigma2)


@pytest.mark.parametrize("mix", [(-2.0, 1.8546), (1.0, 0.5), (0.0, -3.0)])
def test_p_is_the_noise_weighted_log_mean_of_the_fit_led_p_and_the_partners(mix):
    acc, _ = windows(noise=0.03, n=12)
    model, alone = pair(tau_min=1e-8, tau_max=2e-8)
    with torch.no_grad():
        model.mix.copy_(torch.tensor(mix))
        signals = torch.from_numpy(acc)
        p, p_alone = model(signals).double().numpy(), alone(signals).double().numpy()
        p_partner = model.bounded(model.partner_head(model.embed(signals))).double().numpy()
    slope = math.log1p(math.exp(mix[1]))
    m = 1 / (1 + np.exp(-(mix[0] + slope * (np.log(sigma_of(acc)) - math.log(0.1)))))[:, None]
    np.testing.assert_allclose(p, p_alone ** (1 - m) * p_partner**m, rtol=3e-5)  # float32 output
    assert np.abs(p / p_alone - 1).max() > 1e-3  # the partner moved them


def test_clean_windows_stay_exact_whatever_the_share_learned():
    """The gate opens on a clean window (the fit's se is rounding), and the share is (1 - the gate's weight) times
    the logistic: a share near 1 at every noise level still leaves the exact fit."""
    model, _ = pair()
    with torch.no_grad():
        model.mix.copy_(torch.tensor([3.0, -5.0]))  # a share of 0.95 whatever the noise
    acc, truth = windows()
    with torch.no_grad():
        p = model(torch.from_numpy(acc)).double().numpy()
    assert np.abs(p / truth - 1).max() <= 1e-4  # the bound: 0.01%


def test_the_objective_trains_the_partner_on_its_own():
    """The training loss is the objective of the mixed p plus the objective of the partner's p."""
    acc, truth = windows(noise=0.03, n=8)
    model, _ = pair()
    objective = LabelledObjective(p_scale=[1.0, 1.0])
    module = IdentificationModule(model.train(), objective)
    batch = {"signals": torch.from_numpy(acc), "params": torch.from_numpy(truth)}
    loss = module.training_step(batch, 0)
    with torch.no_grad():
        p = model(batch["signals"])
        p_partner = model.bounded(model.partner_head(model.embed(batch["signals"])))
    expected = objective(p, batch) + objective(p_partner, batch)
    torch.testing.assert_close(loss.detach(), expected)
    loss.backward()
    assert model.partner_head.weight.grad.abs().sum() > 0


@pytest.mark.parametrize("arguments", [{"prior": None}, {"partner": "yes"}])
def test_a_partner_without_a_prior_or_not_a_bool_names_its_key(arguments):
    with pytest.raises(ConfigError) as info:
        AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="eiv", **{"prior": PRIOR, "partner": True, **arguments})
    assert info.value.key == "partner"
