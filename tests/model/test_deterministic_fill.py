"""The run's deterministic mode without torch's fill of new tensors (training/build.py): a model trained with
the fill off ends with the same weights, bit for bit, as with torch's default, where any op that read memory it
had not written would see NaN."""

import torch

from hybrid_sysid.model.networks import FastCNN
from hybrid_sysid.model.objectives import HybridObjective


def _trained(fill: bool) -> torch.Tensor:
    saved = torch.utils.deterministic.fill_uninitialized_memory
    deterministic = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)
    torch.utils.deterministic.fill_uninitialized_memory = fill
    try:
        torch.manual_seed(0)
        net = FastCNN([5.0, 500.0], [12.0, 2000.0])
        objective = HybridObjective()
        opt = torch.optim.AdamW(net.parameters(), lr=1e-2)
        g = torch.Generator().manual_seed(1)
        for _ in range(5):
            batch = {"signals": torch.randn(16, 2, 500, generator=g)}
            batch |= {name: torch.randn(16, 500, generator=g) for name in objective.keys}
            loss = objective(net(batch["signals"]), batch)
            opt.zero_grad()
            loss.backward()
            opt.step()
        net.eval()
        with torch.no_grad():
            out = net(torch.randn(8, 2, 500, generator=g))
        return torch.cat([out.flatten()] + [v.flatten().double() for v in net.state_dict().values()])
    finally:
        torch.utils.deterministic.fill_uninitialized_memory = saved
        torch.use_deterministic_algorithms(deterministic)


def test_training_without_the_fill_gives_the_same_weights_as_with_it():
    with_fill, without = _trained(True), _trained(False)
    assert torch.isfinite(with_fill).all()
    assert torch.equal(with_fill, without)
