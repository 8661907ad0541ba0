"""The records of a job that chains runs (experiment=transfer and experiment=tuned, hybrid_sysid.cli.train.run_task):
once every run below it is done, the job's own earlier "failed" or "interrupted" record is removed, a completed one
never; and a re-run rewrites no completed run's config (docs/reliability/search.md)."""

import json

import pytest
from hydra import compose, initialize_config_dir

from hybrid_sysid.cli.report import main as report
from hybrid_sysid.cli.train import run_task
from hybrid_sysid.config import CONF_DIR, ConfigError
from hybrid_sysid.runs.rundir import RunDir, run_record

# experiment=transfer cut to one scenario (car=soft_seat, in tiny_cache) and one adaptation: five runs of 20 steps
TRANSFER = [
    "debug=fast",
    "experiment=transfer",
    "transfer.adapt_objectives=[hybrid]",
    "~transfer.scenarios.body_shift",
    "~transfer.scenarios.continuous",
    "evaluation.windows=[1]",
    "trainer.progress_bar=false",
]
RUNS = ["source", "seat_shift/source", "seat_shift/adapted", "seat_shift/scratch", "seat_shift/oracle"]


def transfer_cfg(cache, *more):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=[*TRANSFER, f"data.cache_dir={cache}", *more])


def files_of(job, names=("metrics.json", "config.yaml", "overrides.yaml")) -> dict:
    """Every record, saved config and overrides file below ``job`` (but the job's own record): path -> bytes."""
    return {p: p.read_bytes() for name in names for p in job.rglob(name) if p != job / "metrics.json"}


@pytest.fixture(scope="module")
def transfer_job(tmp_path_factory, tiny_cache):
    """One seed's transfer job, run once as a sweep's job runs it (run_task with multirun)."""
    job = tmp_path_factory.mktemp("transfer") / "0"
    out = run_task(transfer_cfg(tiny_cache), job, ["seed=0"], multirun=True)
    assert out == {"status": "completed", "runs": RUNS}
    return job


@pytest.mark.parametrize("status", ["interrupted", "failed"])
def test_a_transfer_job_removes_its_stale_record_once_every_run_is_done(transfer_job, tiny_cache, status):
    # what launch/job.py's run.record_end leaves when a signal or an error ended the job earlier
    RunDir(transfer_job).record_end(["seed=0"], 0, status, "interrupted by SIGTERM")
    assert json.loads((transfer_job / "metrics.json").read_text())["status"] == status
    before = files_of(transfer_job)
    out = run_task(transfer_cfg(tiny_cache), transfer_job, ["seed=0"], multirun=True)
    assert out == {"status": "completed", "runs": RUNS}
    assert not (transfer_job / "metrics.json").exists()
    assert files_of(transfer_job) == before  # nothing below it retrained or rewritten
    assert report([transfer_job.parent, f"out={transfer_job.parent.parent / status}"]) == 0  # the sweep's count


def test_a_chain_never_removes_a_completed_record_of_its_job(transfer_job, tiny_cache):
    record = transfer_job / "metrics.json"
    record.write_text(json.dumps(run_record("completed", ["seed=0"], 0, steps=20)))
    before = record.read_bytes()
    try:
        run_task(transfer_cfg(tiny_cache), transfer_job, ["seed=0"], multirun=True)
        assert record.read_bytes() == before
    finally:
        record.unlink()  # the other tests' job has no record of its own


@pytest.mark.parametrize(
    "record, removed",
    [
        (run_record("completed", ["seed=0"], 0), False),
        (run_record("interrupted", ["seed=0"], 0, error="interrupted by SIGINT"), True),
        (run_record("failed", ["seed=0"], 0, error="RuntimeError"), True),
        ('{"status": "completed", "results": [{"split": "te', True),  # damaged: no completed record
    ],
)
def test_the_removal_takes_a_stale_record_never_a_completed_one(tmp_path, record, removed):
    path = tmp_path / "metrics.json"
    path.write_text(record if isinstance(record, str) else json.dumps(record))
    RunDir(tmp_path).drop_stale_record()
    assert path.exists() is not removed
    RunDir(tmp_path / "none").drop_stale_record()  # no record: nothing to do, no error


def test_a_rerun_rewrites_no_completed_runs_config(transfer_job, tiny_cache):
    before = files_of(transfer_job)
    # the same job after a value that is no override changed (a user's --config-dir file, a preset): each run is
    # already completed, so its config stays the one it was trained with
    run_task(transfer_cfg(tiny_cache, "trainer.eval_every_n_steps=5"), transfer_job, ["seed=0"], multirun=True)
    assert files_of(transfer_job) == before
    # other overrides into the same directory: refused, and the completed runs' files stay as they were
    with pytest.raises(ConfigError, match="holds a completed run of other overrides"):
        run_task(transfer_cfg(tiny_cache), transfer_job, ["seed=0", "objective=labelled"], multirun=True)
    assert files_of(transfer_job) == before
