"""A checkpoint that cannot be written whole leaves the previous one as it was: the run's trainer saves beside the
file and renames it over it, never through a temporary file on another file system (fsspec's, in the system's temp
folder, moved by a copy that a full disk cuts short)."""

import pytest
import torch

from hybrid_sysid.training.build import build_trainer


@pytest.mark.faults
def test_a_checkpoint_cut_short_by_a_full_disk_leaves_the_previous_one(make_cfg, small_fs):
    io = build_trainer(make_cfg("data=tiny", "trainer=debug"), small_fs / "run").strategy.checkpoint_io
    best = small_fs / "run" / "checkpoints" / "best.ckpt"
    good = {"state": torch.arange(1000.0)}
    io.save_checkpoint(good, best)
    written = best.read_bytes()
    with pytest.raises(OSError):  # 2 MB into what is left of 1 MiB
        io.save_checkpoint({"state": torch.ones(500_000)}, best)
    assert best.read_bytes() == written
    assert torch.equal(torch.load(best, weights_only=True)["state"], good["state"])
    assert sorted(p.name for p in best.parent.iterdir()) == ["best.ckpt"]  # no temporary file left
