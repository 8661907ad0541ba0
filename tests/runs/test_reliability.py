"""Guards that need no subprocess: completed records are never replaced, resume checks what it resumes, checkpoints
name their files relative to the run, damaged files are recovered from, the cache survives what its disk does."""

import json
import os
import subprocess
import warnings

import numpy as np
import pytest
import torch

from hybrid_sysid.config import ConfigError
from hybrid_sysid.runs.resume import check_resume
from hybrid_sysid.runs.rundir import CompletedRecordError, RunDir, run_record

TINY = ["data=tiny", "trainer=debug", "trainer.max_steps=20", "trainer.eval_every_n_steps=10"]


# ---- records ---------------------------------------------------------------------------------------------------


def test_a_completed_record_is_never_replaced(tmp_path):
    RunDir(tmp_path).write_record(run_record("completed", ["seed=0"], 0))
    before = (tmp_path / "metrics.json").read_bytes()
    for status in ("failed", "interrupted", "completed"):
        with pytest.raises(CompletedRecordError):
            RunDir(tmp_path).write_record(run_record(status, ["seed=1"], 1))
    assert (tmp_path / "metrics.json").read_bytes() == before


def test_a_failed_or_interrupted_record_is_replaced(tmp_path):
    RunDir(tmp_path).write_record(run_record("interrupted", ["seed=0"], 0, error="interrupted by SIGTERM"))
    RunDir(tmp_path).write_record(run_record("completed", ["seed=0"], 0))
    assert json.loads((tmp_path / "metrics.json").read_text())["status"] == "completed"


def test_a_truncated_record_is_no_completed_run(tmp_path):
    RunDir(tmp_path).write_record(run_record("completed", ["seed=0"], 0))
    text = (tmp_path / "metrics.json").read_text()
    (tmp_path / "metrics.json").write_text(text[: len(text) // 2])
    assert RunDir(tmp_path).previous_record(["seed=0"]) is None  # the job runs again
    RunDir(tmp_path).write_record(run_record("completed", ["seed=0"], 0))  # and may write its record


def test_a_completed_run_of_other_overrides_is_refused(tmp_path):
    RunDir(tmp_path).write_record(run_record("completed", ["seed=0"], 0))
    assert RunDir(tmp_path).previous_record(["seed=0", "resume=x"])["status"] == "completed"
    with pytest.raises(ValueError, match="holds a completed run of other overrides"):
        RunDir(tmp_path).previous_record(["seed=1"])


# ---- resume= ---------------------------------------------------------------------------------------------------


def saved_run(tmp_path, make_cfg, *overrides):
    """A directory holding what Hydra saves before a run's first step."""
    from omegaconf import OmegaConf

    run = tmp_path / "run"
    (run / ".hydra").mkdir(parents=True)
    OmegaConf.save(make_cfg(*overrides), run / ".hydra" / "config.yaml")
    return run


def test_resume_refuses_a_directory_without_a_run(tmp_path, make_cfg):
    with pytest.raises(ConfigError, match="resume = .* no such directory"):
        check_resume(RunDir(tmp_path / "missing"), make_cfg())
    with pytest.raises(ConfigError, match="holds no run"):
        check_resume(RunDir(tmp_path), make_cfg())
    assert not (tmp_path / "missing").exists()


def test_resume_refuses_a_run_of_another_config(tmp_path, make_cfg):
    run = saved_run(tmp_path, make_cfg, *TINY, "seed=0")
    with pytest.raises(ConfigError, match=r"another config \(seed = 0 there, 1 here\)"):
        check_resume(RunDir(run), make_cfg(*TINY, "seed=1"))
    with pytest.raises(ConfigError, match="trainer.max_steps = 20 there, 40 here"):
        check_resume(RunDir(run), make_cfg(*TINY, "trainer.max_steps=40"))
    with pytest.raises(ConfigError, match="model.net.channels"):
        check_resume(RunDir(run), make_cfg(*TINY, "model.net.channels=16"))


def test_resume_accepts_the_same_config_from_anywhere(tmp_path, make_cfg):
    run = saved_run(tmp_path, make_cfg, *TINY)
    moved = tmp_path / "moved"
    run.rename(moved)
    # where the run and the cache lie, the progress bar and the profiler cannot change the numbers
    check_resume(
        RunDir(moved), make_cfg(*TINY, f"resume={moved}", "data.cache_dir=elsewhere", "trainer.progress_bar=true")
    )
    check_resume(RunDir(moved), make_cfg(*TINY, "trainer.profiler=simple", "paths.root=elsewhere"))
    with pytest.raises(ConfigError, match="trainer.max_steps"):  # a key beside them still may not change
        check_resume(RunDir(moved), make_cfg(*TINY, "trainer.profiler=simple", "trainer.max_steps=7"))


def test_resume_accepts_other_curve_levels_and_a_config_saved_before_them(tmp_path, make_cfg):
    """noise.curve_std changes which curve rows are recorded, not the weights or the scores: a run saved at every
    level (or before the key existed) continues with curves at fewer levels."""
    from omegaconf import OmegaConf

    run = saved_run(tmp_path, make_cfg, *TINY)
    path = run / ".hydra" / "config.yaml"
    saved = OmegaConf.load(path)
    del saved.noise["curve_std"]
    OmegaConf.save(saved, path)
    check_resume(RunDir(run), make_cfg(*TINY))
    check_resume(RunDir(run), make_cfg(*TINY, "noise.curve_std=[0.0]"))
    with pytest.raises(ConfigError, match="noise.eval_std"):  # the levels of the scores still may not change
        check_resume(RunDir(run), make_cfg(*TINY, "noise.eval_std=[0.0]"))


def test_resume_accepts_a_config_saved_before_the_faults_and_the_noise_range(tmp_path, make_cfg):
    """A run saved before sensor=, car.seat_hardening and noise.train_std_max existed ran what their defaults run:
    it resumes; the same keys at another value are another run."""
    from omegaconf import OmegaConf

    run = saved_run(tmp_path, make_cfg, *TINY)
    path = run / ".hydra" / "config.yaml"
    saved = OmegaConf.load(path)
    for node, key in ((saved, "sensor"), (saved.car, "seat_hardening"), (saved.noise, "train_std_max")):
        del node[key]
    del saved["schema_version"]  # written before the schema had versions
    OmegaConf.save(saved, path)
    check_resume(RunDir(run), make_cfg(*TINY))
    with pytest.raises(ConfigError, match="sensor.skew_max"):
        check_resume(RunDir(run), make_cfg(*TINY, "sensor=skewed"))


def test_resume_with_an_unreadable_saved_config_goes_on(tmp_path, make_cfg, capsys):
    """No refusal: one warning line on stderr naming the file, kept for the run's log file (the command's console
    and train.log: tests/cli/test_run_promises.py)."""
    from hybrid_sysid.runs.resume import uncompared

    run = saved_run(tmp_path, make_cfg, *TINY)
    (run / ".hydra" / "config.yaml").write_text("data: {n_roads: [")  # truncated
    check_resume(RunDir(run), make_cfg(*TINY))
    warned = capsys.readouterr().err.splitlines()
    assert len(warned) == 1 and warned[0].startswith(f"warning: {run / '.hydra' / 'config.yaml'} cannot be read")
    assert warned[0].endswith("resuming without comparing the configs")
    assert uncompared() == [warned[0].removeprefix("warning: ")] and uncompared() == []


def test_resume_reports_a_truncated_config_that_still_parses_as_damaged(tmp_path, make_cfg):
    """A config cut at a line end still parses but lacks the keys after the cut: named as damaged, with the
    command that rewrites it; a key it holds with another value is still another run."""
    run = saved_run(tmp_path, make_cfg, *TINY)
    path = run / ".hydra" / "config.yaml"
    lines = path.read_text().splitlines()
    cut = next(i for i, line in enumerate(lines) if line.startswith("trainer:"))
    path.write_text("\n".join(lines[:cut]) + "\n")
    with pytest.raises(ConfigError, match=r"config.yaml is damaged: it lacks \d+ keys \(car\.c2, ") as err:
        check_resume(RunDir(run), make_cfg(*TINY), ["data=tiny", f"resume={run}"])
    assert f"`hybrid-sysid data=tiny resume={run} --cfg job > {path}`" in str(err.value)
    with pytest.raises(ConfigError, match=r"another config \(seed = 0 there, 1 here; car"):
        check_resume(RunDir(run), make_cfg(*TINY, "seed=1"))


# ---- a run's files, damaged --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A completed in-process run (20 steps, checkpoints at 10 and 20) and its config's overrides."""
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.report.run_figures import write_run_figures
    from hybrid_sysid.training.run import train

    tmp = tmp_path_factory.mktemp("finished")
    overrides = [*TINY, f"data.cache_dir={tmp / 'cache'}", "trainer.progress_bar=false", "trainer.threads=1"]
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
    n = torch.get_num_threads()
    try:
        record = train(cfg, tmp / "run", overrides)
    finally:
        torch.set_num_threads(n)
    write_run_figures(tmp / "run")
    return cfg, overrides, tmp / "run", record


def numbers(record):
    return [(r["split"], r["noise_std"], r["parameter"], r["mean_rel_dev"]) for r in record["results"]]


FILES = [
    "metrics.json",
    "curves.csv",
    "predictions.csv",
    "figures/test_predictions.png",
    "figures/learning_curves.png",
    "checkpoints/last.ckpt",
    "checkpoints/best.ckpt",
    "both checkpoints",
]


@pytest.mark.faults
@pytest.mark.parametrize("name", FILES)
def test_each_file_a_run_writes_truncated_then_the_next_command_recovers(finished, tmp_path, name, caplog):
    """Truncate one file to half its length; for a checkpoint, also drop the record (a run killed after it). The
    job run again completes with the numbers of the undamaged run, and the report reads the directory."""
    import shutil

    from hybrid_sysid.cli.report import main as report
    from hybrid_sysid.training.run import train

    cfg, overrides, done, record = finished
    run = tmp_path / "run"
    shutil.copytree(done, run)
    names = ["checkpoints/last.ckpt", "checkpoints/best.ckpt"] if name == "both checkpoints" else [name]
    for n in names:
        data = (run / n).read_bytes()
        (run / n).write_bytes(data[: len(data) // 2])
    if name.endswith("ckpt") or name == "both checkpoints":
        (run / "metrics.json").unlink()
    n_threads = torch.get_num_threads()
    try:
        again = train(cfg, run, overrides)
    finally:
        torch.set_num_threads(n_threads)
    assert again["status"] == "completed"
    # the tolerance of tests/cli/test_faults.py: a first run in a process may differ from a later one in the last digits
    assert [n[:3] for n in numbers(again)] == [n[:3] for n in numbers(record)]
    assert [n[3] for n in numbers(again)] == pytest.approx([n[3] for n in numbers(record)], rel=1e-5, abs=1e-7)
    if name.endswith("ckpt") or name == "both checkpoints":
        assert "cannot be loaded" in caplog.text
    if name != "checkpoints/last.ckpt" and "ckpt" in name:  # the best weights are lost: trained again
        assert "from the beginning" in caplog.text
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["best.ckpt", "last.ckpt"]
    assert report([run, f"out={tmp_path / 'report'}"]) == 0


def test_checkpoints_name_their_files_relative_to_the_run(finished, tmp_path):
    from hybrid_sysid.training.callbacks import RunCheckpoint

    _, _, run, _ = finished
    state = next(
        v
        for k, v in torch.load(run / "checkpoints" / "last.ckpt", weights_only=True)["callbacks"].items()
        if k.startswith("RunCheckpoint")
    )
    assert state["dirpath"] == "." and state["best_model_path"] == "best.ckpt"
    assert state["last_model_path"] == "last.ckpt" and set(state["best_k_models"]) == {"best.ckpt"}
    moved = RunCheckpoint(dirpath=tmp_path / "elsewhere", filename="best", monitor="val/rel_dev", save_last=True)
    moved.load_state_dict(state)
    assert moved.best_model_score == state["best_model_score"]  # Lightning drops it when the directory changed
    assert moved.best_model_path == str(tmp_path / "elsewhere" / "best.ckpt")
    # a state naming its files by absolute path (versions before 0.2) would take a file outside the run: refused
    absolute = dict(state, best_model_path=str(run / "checkpoints" / "best.ckpt"))
    with pytest.raises(ConfigError, match=r"^resume = .* is not allowed: a run whose checkpoints name their files"):
        moved.load_state_dict(absolute)


def test_the_record_holds_the_thread_count(finished):
    assert finished[3]["threads"] == 1


# ---- the sweep summary ---------------------------------------------------------------------------------------------


def test_a_sweep_whose_jobs_all_failed_still_gets_its_summary(tmp_path):
    from hybrid_sysid.cli.report import main as report
    from hybrid_sysid.report.summary import write_summary

    for i, lr in enumerate(["-1", "1e6"]):
        (tmp_path / str(i)).mkdir()
        RunDir(tmp_path / str(i)).write_record(run_record("failed", [f"model.optim.lr={lr}"], 0, error=f"bad lr {lr}"))
    df, _ = write_summary(tmp_path)
    md = (tmp_path / "summary.md").read_text()
    assert "2 runs: 0 completed, 2 failed" in md and "bad lr 1e6" in md
    assert report([tmp_path]) == 1  # runs failed; not "bad path"


def test_the_summary_warns_when_rows_mix_thread_counts(tmp_path):
    from hybrid_sysid.report.summary import write_summary

    results = [
        {"split": "test", "noise_std": 0.0, "parameter": p, "mean_rel_dev": 0.01, "std_rel_dev": 0.0, "n": 4}
        for p in ("p1", "p2")
    ]
    for i, threads in enumerate([1, 1, 2]):
        (tmp_path / str(i)).mkdir()
        RunDir(tmp_path / str(i)).write_record(
            run_record("completed", [f"seed={i}"], i, results=results, threads=threads)
        )
    df, _ = write_summary(tmp_path)
    assert sorted(df.drop_duplicates("run").threads) == [1, 1, 2]
    assert "different torch thread counts (1, 2)" in (tmp_path / "summary.md").read_text()
    (tmp_path / "2" / "metrics.json").unlink()
    write_summary(tmp_path)
    assert "thread counts" not in (tmp_path / "summary.md").read_text()


# ---- the dataset cache -----------------------------------------------------------------------------------------

SPEC_ARGS = dict(n_roads=3, n_masses=2, n_steps=300)


def dataset(cache, n_steps=300):
    from hybrid_sysid.data.cache import get_dataset
    from hybrid_sysid.data.dataset import DatasetSpec

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = get_dataset(DatasetSpec(**{**SPEC_ARGS, "n_steps": n_steps}), cache)
    return ds, " ".join(str(w.message) for w in caught)


def reference(n_steps=300):
    from hybrid_sysid.data.dataset import DatasetSpec, generate_dataset

    return generate_dataset(DatasetSpec(**{**SPEC_ARGS, "n_steps": n_steps}))


def test_a_directory_in_place_of_the_cache_file_costs_a_warning(tmp_path):
    from hybrid_sysid.data.cache import cache_path
    from hybrid_sysid.data.dataset import DatasetSpec

    cache_path(DatasetSpec(**SPEC_ARGS), tmp_path).mkdir(parents=True)
    ds, warned = dataset(tmp_path)
    assert "not cached" in warned and "using it from memory" in warned
    np.testing.assert_array_equal(ds.seat_acc, reference().seat_acc)


def test_a_killed_writers_temporary_file_is_removed(tmp_path):
    from hybrid_sysid.data.cache import cache_path
    from hybrid_sysid.data.dataset import DatasetSpec

    path = cache_path(DatasetSpec(**SPEC_ARGS), tmp_path)
    stale = path.parent / f".{path.name}.k1ll3d.tmp"  # files.write_atomic's name, left by a SIGKILL
    stale.write_bytes(b"half a dataset")
    dataset(tmp_path)
    assert not stale.exists() and path.is_file()


def test_cache_files_take_the_umask_mode(tmp_path):
    from hybrid_sysid.data.cache import cache_path
    from hybrid_sysid.data.dataset import DatasetSpec

    old = os.umask(0o022)
    try:
        dataset(tmp_path)
    finally:
        os.umask(old)
    assert (cache_path(DatasetSpec(**SPEC_ARGS), tmp_path).stat().st_mode & 0o777) == 0o644  # readable by all


@pytest.mark.faults
def test_a_read_only_cache_holding_a_valid_file_is_read(small_fs):
    ds, _ = dataset(small_fs)
    subprocess.run(["mount", "-o", "remount,ro", str(small_fs)], check=True)
    again, warned = dataset(small_fs)
    # loaded: neither regenerated nor simulated (a simulated dataset would fail to be stored there)
    assert "cannot be locked" in warned and "regenerat" not in warned and "not cached" not in warned
    np.testing.assert_array_equal(again.seat_acc, ds.seat_acc)
    other, warned = dataset(small_fs, n_steps=310)  # not in the cache, and not writable there
    assert "not cached" in warned
    np.testing.assert_array_equal(other.seat_acc, reference(310).seat_acc)


@pytest.mark.faults
def test_a_full_cache_disk_costs_a_warning(small_fs):
    (small_fs / "filler").write_bytes(b"\0" * (1024 * 1024 - 8192))
    ds, warned = dataset(small_fs / "cache")
    assert "not cached" in warned and "No space left" in warned
    np.testing.assert_array_equal(ds.seat_acc, reference().seat_acc)
    assert not list((small_fs / "cache").glob("*.tmp")) and not list((small_fs / "cache").glob(".*.tmp"))
