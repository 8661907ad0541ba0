"""The Trainer path takes exactly the optimisation steps of a plain PyTorch loop.

Lightning's automatic optimisation zeroes the gradients, steps the optimiser and, with the schedule's
``interval: step``, the learning-rate schedule: a schedule stepped per epoch instead, or a doubled optimiser
step, would leave the run training, only differently. The reference here is the loop any PyTorch user would
write, with torch's own OneCycleLR, on the same batches from the same initial weights.
"""

import copy

import lightning as L
import pytest
import torch

from hybrid_sysid.model import FastCNN, HybridObjective, LabelledObjective
from hybrid_sysid.model.module import IdentificationModule

from helpers.paper_prior import P_MAX, P_MIN, P_SCALE

STEPS = 6


@pytest.fixture(scope="module")
def batches(batch_factory):
    return [
        batch_factory(list("ACE"), [60 + 20 * i, 120, 190 - 10 * i], n_steps=800, start=100 + 30 * i, seed=i)
        for i in range(STEPS)
    ]


@pytest.mark.parametrize("objective", [lambda: LabelledObjective(P_SCALE), HybridObjective], ids=["labelled", "hybrid"])
def test_trainer_steps_equal_a_plain_loop(batches, objective, tmp_path):
    torch.manual_seed(0)
    model = IdentificationModule(
        FastCNN(P_MIN, P_MAX, channels=8, n_layers=2), objective(), lr=3e-3, schedule="onecycle", max_steps=STEPS
    )
    plain = copy.deepcopy(model)

    trainer = L.Trainer(
        max_steps=STEPS,
        accelerator="cpu",
        devices=1,
        logger=False,
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        limit_val_batches=0,
        default_root_dir=tmp_path,
    )
    trainer.fit(model, train_dataloaders=torch.utils.data.DataLoader(batches, batch_size=None))
    assert trainer.global_step == STEPS

    opt = torch.optim.AdamW(plain.parameters(), lr=3e-3, weight_decay=0.0)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=3e-3, total_steps=STEPS, pct_start=0.3)
    plain.train()
    for batch in batches:
        loss = plain.objective(plain(batch["signals"]), batch)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()

    trained = model.state_dict()
    for name, ref in plain.state_dict().items():
        torch.testing.assert_close(trained[name], ref, rtol=1e-5, atol=1e-7, msg=f"{name} differs")
    assert model.optimizers().param_groups[0]["lr"] == pytest.approx(opt.param_groups[0]["lr"], rel=1e-12)
    # and the schedule moved: a loop that never stepped it would sit at OneCycleLR's initial max_lr / 25
    assert opt.param_groups[0]["lr"] != pytest.approx(3e-3 / 25)
