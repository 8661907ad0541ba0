"""What a run writes besides its record (docs/reliability/resume.md, "Failures and damaged files"): the tables and
figures replaced whole or not at all, the record's train_seconds across a resume, the warning that names an
unreadable metrics.json. In this process: nothing here is about a process."""

import shutil
import signal

import lightning as L
import pandas as pd
import pytest
import torch

from hybrid_sysid.runs.rundir import RunDir, run_record

pytestmark = pytest.mark.faults


def files(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_the_tables_are_written_atomically(tiny_run, tmp_path, monkeypatch):
    """A write of predictions.csv and curves.csv that fails half-way (a full disk, a signal) leaves the files the
    run had, byte for byte, and no temporary file."""
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    predictions, curves = pd.read_csv(run / "predictions.csv"), pd.read_csv(run / "curves.csv")
    before = files(run)
    real = pd.DataFrame.to_csv

    def half_then_full_disk(frame, path, **kwargs):
        real(frame.head(len(frame) // 2), path, **kwargs)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pd.DataFrame, "to_csv", half_then_full_disk)
    with pytest.raises(OSError, match="No space left"):
        RunDir(run).write_tables(predictions.assign(p1_pred=0.0), curves.assign(mean_rel_dev=0.0))
    assert files(run) == before


def test_the_figures_are_written_atomically(tiny_run, tmp_path, monkeypatch):
    """Drawing a figure that fails after writing part of its file leaves the figure the run had and no temporary
    file; drawn whole, each replaces the earlier one."""
    import matplotlib.figure

    from hybrid_sysid.report.run_figures import write_run_figures

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    write_run_figures(run)
    before = files(run)
    assert {p.name for p in (run / "figures").iterdir()} == {"test_predictions.png", "learning_curves.png"}

    def cut_short(fig, path, **kwargs):
        with open(path, "wb") as f:
            f.write(b"\x89PNG cut short")
        raise OSError(28, "No space left on device")

    with monkeypatch.context() as patch:
        patch.setattr(matplotlib.figure.Figure, "savefig", cut_short)
        with pytest.raises(OSError, match="No space left"):
            write_run_figures(run)
    assert files(run) == before
    (run / "figures" / "test_predictions.png").write_bytes(b"an older figure")
    write_run_figures(run)
    assert (run / "figures" / "test_predictions.png").read_bytes()[:4] == b"\x89PNG"
    assert {p.name for p in (run / "figures").iterdir()} == {"test_predictions.png", "learning_curves.png"}


def test_train_seconds_adds_the_time_of_both_parts(tiny_cache, tmp_path, monkeypatch, make_cfg):
    """A run stopped after its checkpoint at step 10 and resumed: its record's train_seconds is the time its
    checkpoint holds (planted here as 1000 s, a time no 20-step run takes) plus the second part's, which the
    record's fit_seconds bounds (the whole of trainer.fit, validations included)."""
    import hybrid_sysid.training.run as run_module
    from hybrid_sysid.core import stop
    from hybrid_sysid.core.stop import Interrupted

    overrides = ["data=tiny", "trainer=debug", "trainer.max_steps=20", "trainer.eval_every_n_steps=10"]
    cfg = make_cfg(*overrides, f"data.cache_dir={tiny_cache}", "trainer.threads=1")
    run = tmp_path / "run"

    class StopAfterTen(L.Callback):  # as a SIGTERM at step 11 would: the stop requested, raised at the safe point
        def on_train_batch_start(self, trainer, pl_module, batch, batch_idx):
            if trainer.global_step == 10:
                stop.request(signal.SIGTERM)

    with monkeypatch.context() as patch:
        patch.setattr(run_module, "build_callbacks", lambda cfg, monitor: [StopAfterTen()])
        try:
            with pytest.raises(Interrupted):
                run_module.train(cfg, run, overrides)
        finally:
            stop.reset()
    last = run / "checkpoints" / "last.ckpt"
    checkpoint = torch.load(last, weights_only=True)
    assert checkpoint["global_step"] == 10 and not (run / "metrics.json").exists()
    clock = next(k for k in checkpoint["callbacks"] if k.startswith("TrainingClock"))
    first = checkpoint["callbacks"][clock]["seconds"]
    assert 0 < first < 1000
    checkpoint["callbacks"][clock]["seconds"] = 1000.0
    torch.save(checkpoint, last)

    record = run_module.train(cfg, run, overrides)
    assert record["status"] == "completed" and record["steps"] == 20
    assert 1000.0 < record["train_seconds"] <= 1000.0 + record["fit_seconds"] + 0.01  # both rounded to 0.01 s
    curves = pd.read_csv(run / "curves.csv")
    assert (curves[curves.step == 10].seconds < 1000).all() and (curves[curves.step == 20].seconds > 1000).all()


def test_the_warning_names_an_unreadable_record(tmp_path, caplog):
    """A truncated metrics.json is no completed run (the job runs again), and the warning says which file."""
    RunDir(tmp_path).write_record(run_record("completed", ["seed=0"], 0))
    text = (tmp_path / "metrics.json").read_text()
    (tmp_path / "metrics.json").write_text(text[: len(text) // 2])
    assert RunDir(tmp_path).previous_record(["seed=0"]) is None
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) == 1 and f"run = {tmp_path} is not allowed: its metrics.json is damaged" in warned[0]
    assert warned[0].endswith("running the job again")
