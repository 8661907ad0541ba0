"""objective=label_free trains without labels: with every label replaced by garbage, the same weights to the
bit, and its model selection reads no labels (val/loss)."""

import torch

from hybrid_sysid.training.run import train

TINY = ["data=tiny", "trainer=debug", "objective=label_free"]


def test_label_free_training_never_reads_labels(make_cfg, tmp_path, poison_labels):
    clean = train(make_cfg(*TINY), tmp_path / "clean", [])
    poison_labels()
    poisoned = train(make_cfg(*TINY, f"data.cache_dir={tmp_path / 'other'}"), tmp_path / "poisoned", [])
    assert clean["monitor"] == poisoned["monitor"] == "val/loss"
    assert clean["best_score"] == poisoned["best_score"]
    a, b = (
        torch.load(tmp_path / d / "checkpoints" / "best.ckpt", weights_only=True)["state_dict"]
        for d in ("clean", "poisoned")
    )
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert clean["results"] != poisoned["results"]  # the poison reached the labels: the scores, which use them, differ
