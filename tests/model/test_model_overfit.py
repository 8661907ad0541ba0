"""FastCNN must memorise a tiny training set under either objective (a wiring check, not a benchmark)."""

import pytest
import torch

from hybrid_sysid.model import FastCNN, HybridObjective, LabelledObjective

from paper_prior import P_MAX, P_MIN, P_SCALE


@pytest.fixture(scope="module")
def tiny_set(batch_factory):
    # 8 recordings, every road class, masses across the whole prior; one fixed window each
    return batch_factory(list("ABCDEACE"), [50, 70, 90, 110, 130, 150, 175, 200], n_steps=800, start=300)


def mean_rel_dev(model, batch):
    model.eval()
    with torch.no_grad():
        pred = model(batch["signals"])
    model.train()
    return ((pred - batch["params"]).abs() / batch["params"]).mean(dim=0)  # per parameter


@pytest.mark.parametrize("objective", [LabelledObjective(P_SCALE), HybridObjective()], ids=["labelled", "hybrid"])
def test_fast_cnn_overfits_a_tiny_set(tiny_set, objective):
    torch.manual_seed(0)
    model = FastCNN(P_MIN, P_MAX, channels=16, n_layers=3, bn_momentum=0.1)  # 300 steps: running stats must catch up
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    # a constant prediction at the prior's centre misses by ~30%: the bar below needs real learning
    baseline = ((tiny_set["params"] - tiny_set["params"].mean(0)).abs() / tiny_set["params"]).mean().item()
    assert baseline > 0.25
    for _ in range(300):
        loss = objective(model(tiny_set["signals"]), tiny_set)
        opt.zero_grad()
        loss.backward()
        opt.step()
    # measured 0.04-2.0% per parameter after 300 steps over seeds 0-3; 5% leaves room without losing meaning
    assert (mean_rel_dev(model, tiny_set) < 0.05).all()
