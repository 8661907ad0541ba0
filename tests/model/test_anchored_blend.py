"""model.net.blend: in evaluation the anchored estimator's p is the mean in log p of the network's p and the
window's Bayes estimate. References: baseline=eiv_bayes (ErrorsInVariablesBayes) on the same windows, computed
here, and the network's own output in training mode, which the blend never touches."""

import numpy as np
import pytest
import torch
from test_anchored import DT, P_MAX, P_MIN, windows
from test_anchored_prior import PRIOR

from hybrid_sysid.baselines.eiv_bayes import ErrorsInVariablesBayes
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.model.anchored import AnchoredCNN


def net(blend, prior=PRIOR, **kwargs):
    torch.manual_seed(0)
    model = AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="eiv", prior=prior, trunk=False, blend=blend, **kwargs)
    with torch.no_grad():  # a trained head's factor and gate, not the zeros it starts from
        model.head[-1].bias.copy_(torch.tensor([0.3, -0.2, -2.0, 1.0]))
    return model


def outputs(model, acc):
    """(training-mode p, evaluation-mode p) of the same windows, float64."""
    with torch.no_grad():
        return tuple(model.train(mode)(torch.from_numpy(acc)).double().numpy() for mode in (True, False))


@pytest.mark.parametrize("g", [0.0, 0.3, 1.0])
def test_evaluated_p_is_the_log_mean_of_the_network_and_the_bayes_estimate(g):
    acc, _ = windows(noise=0.03, n=12)
    trained, evaluated = outputs(net(g), acc)
    x = acc.astype(np.float64)
    p_bayes = ErrorsInVariablesBayes(prior=PRIOR, dt=DT).fit_windows(x[:, 0], x[:, 1], DT, "consistent")[0]
    np.testing.assert_allclose(evaluated, trained**g * p_bayes ** (1 - g), rtol=3e-5)  # float32 output
    if g < 1:
        assert np.abs(evaluated / trained - 1).max() > 1e-3  # the Bayes estimate moved some of them


def test_the_blend_helps_where_the_network_is_off():
    """A head far off the fit (its factor near 2 and its gate shut) on windows at noise 0.03: the Bayes estimate
    pulls the blend back, so its mean relative deviation is below the network's own."""
    acc, truth = windows(noise=0.03, n=24)
    model = net(0.5)
    with torch.no_grad():
        model.head[-1].bias.copy_(torch.tensor([3.0, 3.0, -20.0, -20.0]))
    trained, evaluated = outputs(model, acc)
    assert np.abs(evaluated / truth - 1).mean() < 0.8 * np.abs(trained / truth - 1).mean()


def test_clean_windows_stay_exact_with_the_blend():
    acc, truth = windows()
    _, evaluated = outputs(net(0.5), acc)
    assert np.abs(evaluated / truth - 1).max() <= 1e-4  # the bound: 0.01%


@pytest.mark.parametrize(
    "arguments",
    [{"fix": "gain"}, {"prior": {**PRIOR, "seat_spread": 0.0}}, {"prior": None}],
    ids=["fault-fix", "no-spread", "no-prior"],
)
def test_no_blend_where_the_bayes_estimate_is_not_defined(arguments):
    acc, _ = windows(noise=0.03, n=6)
    model = net(0.5, **arguments)
    assert model.bayes is None
    trained, evaluated = outputs(model, acc)
    np.testing.assert_array_equal(evaluated, trained)


@pytest.mark.parametrize("blend", [-0.1, 1.5, "half", True, float("nan")])
def test_a_blend_outside_0_1_names_its_key(blend):
    with pytest.raises(ConfigError) as info:
        net(blend)
    assert info.value.key == "blend"
