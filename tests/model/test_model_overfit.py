"""FastCNN must memorise a tiny training set under either objective (a wiring check, not a benchmark)."""

import pytest
import torch

from hybrid_sysid.model import FastCNN, HybridObjective, LabelledObjective

from helpers.paper_prior import P_MAX, P_MIN, P_SCALE


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
    # the reference, computed here: a constant prediction (the set's mean for every recording) misses by 44% per
    # parameter (the untrained net: 37-52%); the bar below is relative to it, not to one CPU's rounding
    baseline = ((tiny_set["params"] - tiny_set["params"].mean(0)).abs() / tiny_set["params"]).mean(dim=0)
    assert (baseline > 0.25).all()
    for _ in range(300):
        loss = objective(model(tiny_set["signals"]), tiny_set)
        opt.zero_grad()
        loss.backward()
        opt.step()
    # trained, per parameter, over seeds 0-7 on an Intel Xeon: labelled 0.45-5.6% (seed 0, the one run here:
    # 5.6% and 5.3%), hybrid 0.02-2.6%; on an AMD EPYC 0.04-2.0% over seeds 0-3. The bar, a third of the constant
    # guess (15%), is 2.6x above the worst measured and 2.5-3.5x below an untrained net: it means "learned"
    assert (mean_rel_dev(model, tiny_set) < baseline / 3).all()
