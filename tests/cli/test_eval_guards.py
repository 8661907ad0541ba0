"""What hybrid-sysid-eval and init_from= make of a received run that is damaged, cut short, still training or
never ended, and of a directory another process holds (docs/reliability/eval.md, run.md). Each command runs its
main() in this process (cli_in_process in conftest.py): a refusal ends before any work, and an evaluation of
data=tiny reads the shared dataset cache."""

import json
import shutil
import subprocess

import pytest
import torch

from helpers.tree import snapshot

pytestmark = pytest.mark.faults


@pytest.fixture(autouse=True)
def no_figures(monkeypatch):
    """An evaluation draws no figures here (seconds each; the test of figures that cannot be drawn sets its own)."""
    import hybrid_sysid.report.run_figures as run_figures

    monkeypatch.setattr(run_figures, "write_run_figures", lambda run_dir: None)


def eval_cli(cli_in_process, tmp_path, *args, env=None):
    from hybrid_sysid.cli.evaluate import main

    code, out, err = cli_in_process(main, *args, cwd=tmp_path, env=env)
    return subprocess.CompletedProcess(args, code, out, err)


def one_line(proc, *words):
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr[-2000:]
    assert all(w in lines[0] for w in words), lines[0]


def copy_of(tiny_run, where):
    shutil.copytree(tiny_run, where)
    return where


def cut_after(run, key):
    """The run's saved config cut at the line's end after the line of ``key`` (as saved, indented): it parses."""
    path = run / ".hydra" / "config.yaml"
    lines = path.read_text().splitlines(keepends=True)
    cut = next(i for i, line in enumerate(lines) if line.startswith(key)) + 1
    path.write_text("".join(lines[:cut]))


def test_a_cut_run_evaluated_into_its_completed_evaluation_changes_nothing(tiny_run, tmp_path, cli_in_process):
    """The source's config cut after trainer.max_steps still parses and has every section: the keys after the cut
    would take the schema's defaults. Evaluated again into the evaluation it made when whole, with the same
    overrides, it is refused in one line, and no file of that completed evaluation changes."""
    source = copy_of(tiny_run, tmp_path / "source")
    done = tmp_path / "done"
    first = eval_cli(cli_in_process, tmp_path, f"run={source}", f"hydra.run.dir={done}")
    assert first.returncode == 0, first.stderr[-2000:]
    cut_after(source, "  max_steps:")
    before = {p: p.read_bytes() for p in done.rglob("*") if p.is_file() and p.suffix != ".log"}
    proc = eval_cli(cli_in_process, tmp_path, f"run={source}", f"hydra.run.dir={done}")
    one_line(proc, f"run = {source}", "saved config is complete", "trainer.accelerator", "cut short")
    assert {p: p.read_bytes() for p in done.rglob("*") if p.is_file() and p.suffix != ".log"} == before


def test_a_completed_evaluation_run_again_is_skipped_without_writing_its_config(tiny_run, tmp_path, cli_in_process):
    """The evaluation's own saved config (the evaluated one) is never written again over a completed
    evaluation, even when the source's config now gives another (a key the schema fills the same way)."""
    source = copy_of(tiny_run, tmp_path / "source")
    done = tmp_path / "done"
    args = [f"run={source}", f"hydra.run.dir={done}"]
    assert eval_cli(cli_in_process, tmp_path, *args).returncode == 0
    saved = done / ".hydra" / "config.yaml"
    saved.write_text(saved.read_text() + "# the completed evaluation's file\n")
    before = {p: p.read_bytes() for p in done.rglob("*") if p.is_file() and p.suffix != ".log"}
    proc = eval_cli(cli_in_process, tmp_path, *args)
    assert proc.returncode == 0 and "already completed" in proc.stdout, proc.stderr[-2000:]
    assert {p: p.read_bytes() for p in done.rglob("*") if p.is_file() and p.suffix != ".log"} == before


def test_an_init_from_a_cut_run_into_a_completed_run_names_the_file_and_changes_nothing(
    tiny_run, tmp_path, cli_in_process
):
    """init_from= a run whose config is cut inside its network's section: one line naming the file and the
    arguments it lacks, exit 2, and the completed run of these very overrides in hydra.run.dir is untouched."""
    from hybrid_sysid.cli.train import main as train

    source = copy_of(tiny_run, tmp_path / "source")
    cut_after(source, "    channels:")
    done = copy_of(tiny_run, tmp_path / "done")
    args = ["data=tiny", "trainer=debug", "trainer.max_steps=5", f"init_from={source}"]
    record = json.loads((done / "metrics.json").read_text())
    (done / "metrics.json").write_text(json.dumps({**record, "overrides": args}))  # a completed run of them
    before = snapshot(tmp_path)
    code, out, err = cli_in_process(train, *args, f"hydra.run.dir={done}", cwd=tmp_path)
    one_line(
        subprocess.CompletedProcess(args, code, out, err),
        f"init_from = {source}",
        ".hydra/config.yaml has no value for model.net.downsample, model.net.kernel_size, model.net.n_layers",
    )
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "command, damaged",
    [("eval", ".hydra/config.yaml"), ("eval", "metrics.json"), ("init_from", ".hydra/config.yaml")],
)
def test_a_run_whose_saved_config_or_record_is_damaged_is_one_line_naming_the_file(
    tiny_run, tmp_path, cli_in_process, command, damaged
):
    """A garbled config, a truncated record: one line naming the file, exit 2, nothing written (init_from= reads
    the config and the weights alone)."""
    from hybrid_sysid.cli.train import main as train

    source = copy_of(tiny_run, tmp_path / "source")
    text = (source / damaged).read_text()
    (source / damaged).write_text(text[: len(text) // 2] + ("\n  : [" if damaged.endswith("yaml") else ""))
    out_dir = tmp_path / "out"
    before = snapshot(tmp_path)
    if command == "eval":
        proc = eval_cli(cli_in_process, tmp_path, f"run={source}", f"hydra.run.dir={out_dir}")
    else:
        args = ["data=tiny", "trainer=debug", "trainer.max_steps=5", f"init_from={source}", f"hydra.run.dir={out_dir}"]
        code, out, err = cli_in_process(train, *args, cwd=tmp_path)
        proc = subprocess.CompletedProcess(args, code, out, err)
    one_line(proc, f"{'run' if command == 'eval' else 'init_from'} = {source}", f"its {damaged} is damaged")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["eval", "init_from"])
def test_a_run_still_training_is_not_evaluated_nor_started_from(tiny_run, tmp_path, cli_in_process, command):
    """Its writer lock held (as a run in training holds it, from before Hydra writes there) and no record yet:
    one line saying so, exit 2, nothing written: its checkpoints are not yet what it will leave."""
    from hybrid_sysid.cli.train import main as train
    from hybrid_sysid.runs.locks import hold_for_writing

    source = copy_of(tiny_run, tmp_path / "source")
    (source / "metrics.json").unlink()
    out_dir = tmp_path / "out"
    lock = hold_for_writing(source, "hydra.run.dir")  # another open file: to flock, another writer
    before = snapshot(tmp_path)
    try:
        if command == "eval":
            proc = eval_cli(cli_in_process, tmp_path, f"run={source}", f"hydra.run.dir={out_dir}")
        else:
            args = ["data=tiny", "trainer=debug", "trainer.max_steps=5", f"init_from={source}"]
            code, out, err = cli_in_process(train, *args, f"hydra.run.dir={out_dir}", cwd=tmp_path)
            proc = subprocess.CompletedProcess(args, code, out, err)
    finally:
        lock.release()
    one_line(proc, f"{'run' if command == 'eval' else 'init_from'} = {source}", "another process is still writing it")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("record", [None, "interrupted"])
def test_a_run_that_never_completed_is_evaluated_with_a_warning_naming_its_checkpoint(
    tiny_run, tmp_path, cli_in_process, record
):
    """Killed (no record) or interrupted, and no process writing it: its best checkpoint is evaluated, with a
    warning naming it and its step; the record gives the step the checkpoint was saved at and the source's
    status, not the steps 0 of a record that never completed."""
    from hybrid_sysid.runs.rundir import RunDir, run_record

    source = copy_of(tiny_run, tmp_path / "source")
    (source / "metrics.json").unlink()
    if record:
        RunDir(source).write_record(run_record(record, [], 0, error="interrupted by SIGTERM"))
    saved_at = torch.load(source / "checkpoints" / "best.ckpt", weights_only=True)["global_step"]
    out_dir = tmp_path / "out"
    proc = eval_cli(cli_in_process, tmp_path, f"run={source}", f"hydra.run.dir={out_dir}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    status = record or "no record"
    warning = f"run {source} has no completed record ({status}): evaluating its checkpoints/best.ckpt, saved at step"
    assert f"{warning} {saved_at}" in proc.stdout + proc.stderr
    evaluation = json.loads((out_dir / "metrics.json").read_text())
    assert evaluation["status"] == "completed" and evaluation["source_status"] == status
    assert evaluation["steps"] == saved_at > 0


def test_a_second_process_writing_into_the_evaluations_directory_is_refused(tiny_run, tmp_path, cli_in_process):
    """The evaluation's directory held by another writer: one line, exit 2, before Hydra writes anything."""
    from hybrid_sysid.runs.locks import hold_for_writing

    out_dir = tmp_path / "out"
    out_dir.mkdir()
    (out_dir / "mine.txt").write_text("the first writer's file")
    lock = hold_for_writing(out_dir, "hydra.run.dir")
    try:
        before = snapshot(tmp_path)
        proc = eval_cli(cli_in_process, tmp_path, f"run={tiny_run}", f"hydra.run.dir={out_dir}")
        assert snapshot(tmp_path) == before
    finally:
        lock.release()
    one_line(proc, f"hydra.run.dir = {out_dir}", "another process is writing there")


def test_an_evaluations_figures_that_cannot_be_drawn_are_a_warning(tiny_run, tmp_path, cli_in_process, monkeypatch):
    import hybrid_sysid.report.run_figures as run_figures

    def broken(run_dir):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(run_figures, "write_run_figures", broken)
    out_dir = tmp_path / "out"
    proc = eval_cli(cli_in_process, tmp_path, f"run={tiny_run}", f"hydra.run.dir={out_dir}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert f"run figures not drawn in {out_dir}: OSError" in proc.stdout + proc.stderr
    assert json.loads((out_dir / "metrics.json").read_text())["status"] == "completed"


def test_a_sweep_over_runs_evaluates_each(tiny_run, tmp_path, cli_in_process):
    """run= swept (adversarial case B44): the sweep's checks read its config unresolved, so the mandatory run=,
    given per job only, cannot stop them; each job evaluates its own run."""
    a, b = copy_of(tiny_run, tmp_path / "a"), copy_of(tiny_run, tmp_path / "b")
    sw = tmp_path / "sw"
    proc = eval_cli(cli_in_process, tmp_path, "-m", f"run={a},{b}", "car=paper", f"hydra.sweep.dir={sw}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    records = [json.loads(p.read_text()) for p in sorted(sw.glob("*/metrics.json"))]
    assert [r["status"] for r in records] == ["completed", "completed"]
    assert sorted(r["source_run"] for r in records) == [str(a), str(b)]


def test_a_received_config_asking_for_a_huge_network_is_refused_before_it_is_built(tiny_run, tmp_path, cli_in_process):
    """200,000 channels (adversarial case B47): 1.4 TB of weights that validate would build for real before the
    checkpoint was compared."""
    run = copy_of(tiny_run, tmp_path / "run")
    config = run / ".hydra" / "config.yaml"
    text = config.read_text()
    assert "\n    channels: 32\n" in text
    config.write_text(text.replace("\n    channels: 32\n", "\n    channels: 200000\n"))
    out_dir = tmp_path / "out"
    proc = eval_cli(cli_in_process, tmp_path, f"run={run}", f"hydra.run.dir={out_dir}")
    # the cap on a network's weights (1e8) refuses it before anything is built or compared with the checkpoint
    one_line(proc, "model.net.channels = 200000 is not allowed", "at most 1e+08 weights")
    assert not out_dir.exists()
