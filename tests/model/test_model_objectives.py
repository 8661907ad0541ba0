import numpy as np
import pytest
import torch

from hybrid_sysid.model import CombinedObjective, HybridObjective, LabelledObjective

from helpers.paper_prior import P_SCALE


class LabelGuard(dict):
    """A batch whose labels raise when read: proof that an objective is label-free."""

    def __getitem__(self, key):
        if key == "params":
            raise AssertionError("the objective read the labels")
        return super().__getitem__(key)


def test_hybrid_is_zero_at_the_true_p_and_grows_away_from_it(consistent_batch):
    hybrid = HybridObjective()
    p = consistent_batch["params"]
    at_truth = hybrid(p, consistent_batch).item()
    assert at_truth < 1e-6 * hybrid(1.2 * p, consistent_batch).item()
    factors = [0.7, 0.85, 0.95, 1.0, 1.05, 1.15, 1.3]
    for j in range(2):
        losses = []
        for f in factors:
            q = p.clone()
            q[:, j] *= f
            losses.append(hybrid(q, consistent_batch).item())
        below, above = losses[:4], losses[3:]
        assert all(a > b for a, b in zip(below, below[1:])), (j, losses)  # falls towards the truth
        assert all(a < b for a, b in zip(above, above[1:])), (j, losses)  # and rises past it


def test_hybrid_matches_a_hand_written_reference():
    rng = np.random.default_rng(1)
    z, rv, rd = rng.normal(size=(3, 4, 50))
    pred = np.abs(rng.normal(size=(4, 2))) * [8.0, 1000.0]
    ref_plain = np.mean([np.mean((z[i] + pred[i, 0] * rv[i] + pred[i, 1] * rd[i]) ** 2) for i in range(4)])
    ref_norm = np.mean(
        [np.mean((z[i] + pred[i, 0] * rv[i] + pred[i, 1] * rd[i]) ** 2) / np.mean(z[i] ** 2) for i in range(4)]
    )
    t = lambda a: torch.tensor(a, dtype=torch.float64)  # noqa: E731
    batch = {"signals": t(np.stack([z, -z], axis=1)), "rel_vel": t(rv), "rel_disp": t(rd)}
    assert HybridObjective(normalize=False)(t(pred), batch).item() == pytest.approx(ref_plain, rel=1e-12)
    # rel 1e-9, not 1e-12: the default eps = 1e-12 sits in the denominator
    assert HybridObjective(normalize=True)(t(pred), batch).item() == pytest.approx(ref_norm, rel=1e-9)


def test_hybrid_normalisation_weighs_rough_and_smooth_roads_alike(consistent_batch):
    # scaling a recording by 16 (class A -> E road amplitude) leaves its normalised loss alone
    p = 1.1 * consistent_batch["params"]
    loud = {k: 16.0 * v if k != "params" else v for k, v in consistent_batch.items()}
    norm, plain = HybridObjective(normalize=True), HybridObjective(normalize=False)
    assert norm(p, loud).item() == pytest.approx(norm(p, consistent_batch).item(), rel=1e-5)
    assert plain(p, loud).item() == pytest.approx(256.0 * plain(p, consistent_batch).item(), rel=1e-5)


@pytest.mark.parametrize(
    "objective",
    [
        HybridObjective(),
        HybridObjective(normalize=False),
        CombinedObjective(P_SCALE, labelled_weight=0.0, hybrid_weight=1.0),
    ],
)
def test_hybrid_never_reads_labels(consistent_batch, objective):
    def loss_and_grad(batch):
        pred = (1.1 * consistent_batch["params"]).requires_grad_()
        loss = objective(pred, batch)
        loss.backward()
        return loss.detach(), pred.grad

    ref_loss, ref_grad = loss_and_grad(consistent_batch)
    garbage = [
        torch.full_like(consistent_batch["params"], float("nan")),
        torch.randn_like(consistent_batch["params"]) * 1e6,
    ]
    for params in garbage:
        loss, grad = loss_and_grad({**consistent_batch, "params": params})
        assert torch.equal(loss, ref_loss) and torch.equal(grad, ref_grad)
    loss, grad = loss_and_grad(LabelGuard({k: v for k, v in consistent_batch.items() if k != "params"}))
    assert torch.equal(loss, ref_loss) and torch.equal(grad, ref_grad)


def test_labelled_is_l1_in_scaled_units():
    pred = torch.tensor([[8.0, 1300.0], [4.0, 600.0]])
    batch = {"params": torch.tensor([[7.7, 1237.0], [5.0, 500.0]])}
    by_hand = ((0.3 / 7.7 + 63 / 1237) + (1 / 7.7 + 100 / 1237)) / 2
    assert LabelledObjective(p_scale=(7.7, 1237.0))(pred, batch).item() == pytest.approx(by_hand, rel=1e-6)
    by_hand_other_scale = ((0.3 / 2 + 63 / 100) + (1 / 2 + 100 / 100)) / 2
    assert LabelledObjective(p_scale=(2, 100))(pred, batch).item() == pytest.approx(by_hand_other_scale, rel=1e-6)
    assert LabelledObjective(P_SCALE)(batch["params"], batch).item() == 0.0


def test_combined_is_the_weighted_sum(consistent_batch):
    pred = consistent_batch["params"] * torch.tensor([0.9, 1.2])
    lab, hyb = LabelledObjective(P_SCALE)(pred, consistent_batch), HybridObjective()(pred, consistent_batch)
    assert lab > 0 and hyb > 0
    combined = CombinedObjective(P_SCALE, labelled_weight=0.3, hybrid_weight=2.0)(pred, consistent_batch)
    assert combined.item() == pytest.approx(0.3 * lab.item() + 2.0 * hyb.item(), rel=1e-6)
    only_lab = CombinedObjective(P_SCALE, labelled_weight=1.0, hybrid_weight=0.0)(pred, consistent_batch)
    assert only_lab.item() == pytest.approx(lab.item(), rel=1e-6)


def test_label_use_is_declared_for_model_selection():
    # train.py picks the checkpoint metric from this flag; a label-free objective must not select on labels
    assert HybridObjective().uses_labels is False
    assert CombinedObjective(P_SCALE, labelled_weight=0.0, hybrid_weight=1.0).uses_labels is False
    assert LabelledObjective(P_SCALE).uses_labels is True
    assert CombinedObjective(P_SCALE, labelled_weight=0.5, hybrid_weight=1.0).uses_labels is True


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"labelled_weight": 0.0, "hybrid_weight": 0.0}, "labelled_weight and hybrid_weight must not both be zero"),
        ({"labelled_weight": -1.0}, "labelled_weight = -1.*>= 0"),
        ({"hybrid_weight": -0.5}, "hybrid_weight = -0.5.*>= 0"),
        ({"hybrid_weight": float("nan")}, "hybrid_weight = nan"),
    ],
)
def test_combined_rejects_bad_weights(kwargs, match):
    with pytest.raises(ValueError, match=match):
        CombinedObjective(P_SCALE, **kwargs)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: LabelledObjective(p_scale=(0.0, 1.0)), "p_scale"),
        (lambda: HybridObjective(weighting="ols"), "weighting = 'ols'"),
    ],
)
def test_objectives_reject_bad_arguments(make, match):
    with pytest.raises(ValueError, match=match):
        make()
