"""Validation always runs at the end of training (training.callbacks.ValidateAtEnd): a run shorter than
trainer.eval_every_n_steps, or one whose last step is not a multiple of it, is validated at its last step and
has a best checkpoint (a hyperparameter search scores a trial by that figure)."""

import pandas as pd
import pytest
import torch

from hybrid_sysid.training.run import train


@pytest.mark.parametrize("max_steps, validated", [(3, [3]), (7, [5, 7]), (10, [5, 10])])
def test_the_last_step_is_validated_once(make_cfg, tmp_path, max_steps, validated):
    cfg = make_cfg(
        "data=tiny",
        "trainer=debug",
        f"trainer.max_steps={max_steps}",
        "trainer.eval_every_n_steps=5",
        "trainer.curve_every_n_steps=null",
    )
    record = train(cfg, tmp_path / "run", [])
    curves = pd.read_csv(tmp_path / "run" / "curves.csv")
    assert sorted(set(curves.step)) == validated  # a curve point at every validation, each step once
    assert record["status"] == "completed" and record["best_score"] is not None
    best = torch.load(tmp_path / "run" / "checkpoints" / "best.ckpt", weights_only=True)
    assert best["global_step"] in validated
