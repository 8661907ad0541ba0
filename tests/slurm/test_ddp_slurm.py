"""DDP inside a SLURM allocation: two tasks of one job (srun), as Lightning's SLURM environment reads them, train
as two ranks into one run directory, write one record, and give the numbers of trainer=ddp outside SLURM (Lightning
starting the second rank itself). Marked ``slurm``: ``pytest -m slurm tests/slurm``, on a cluster such as
scripts/slurm/setup.sh sets up."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from helpers.app_process import run_app, user_env
from helpers.slurm_accounting import settled

pytestmark = [pytest.mark.slurm, pytest.mark.integration]
COMMAND = ["data=tiny", "trainer=ddp", "trainer.max_steps=12", "trainer.eval_every_n_steps=6", "trainer.threads=1"]


@pytest.fixture
def cluster():
    if shutil.which("sbatch") is None:
        pytest.skip("no sbatch on PATH: no SLURM here (scripts/slurm/setup.sh sets up a single-node cluster)")
    if subprocess.run(["scontrol", "ping"], capture_output=True).returncode != 0:
        pytest.skip("SLURM's controller does not answer (scontrol ping)")


def scores(run_dir):
    record = json.loads((run_dir / "metrics.json").read_text())
    keys = ("split", "noise_std", "windows", "parameter")
    return record, {tuple(r[k] for k in keys): (r["mean_rel_dev"], r["std_rel_dev"]) for r in record["results"]}


def test_two_tasks_of_one_job_train_as_two_ranks_and_write_one_record(cluster, tmp_path, tiny_cache):
    run = tmp_path / "run"
    job = tmp_path / "job.sh"
    args = " ".join([*COMMAND, f"hydra.run.dir={run}", f"data.cache_dir={tiny_cache}"])
    job.write_text(f"#!/bin/bash\nsrun --kill-on-bad-exit=1 {sys.executable} -m hybrid_sysid {args}\n")
    sbatch = ["sbatch", "--wait", "--parsable", "--job-name=hybrid-sysid-ddp", "--nodes=1", "--ntasks-per-node=2"]
    sbatch += ["--cpus-per-task=1", "--mem=4G", "--time=10", f"--output={tmp_path / 'job.out'}", str(job)]
    done = subprocess.run(sbatch, cwd=tmp_path, env=user_env(), capture_output=True, text=True, timeout=900)
    output = (tmp_path / "job.out").read_text(errors="replace") if (tmp_path / "job.out").exists() else ""
    assert done.returncode == 0, done.stderr[-2000:] + output[-3000:]
    job_id = done.stdout.strip().split(";")[0]
    state = settled(job_id)  # accounting lags the job's end
    assert [s for _, s in state] == ["COMPLETED"], state
    assert output.count("p1 mean rel. dev.") == 1, output[-3000:]  # one table, printed by global rank 0
    assert list(tmp_path.rglob("metrics.json")) == [run / "metrics.json"]
    assert not list(run.glob("*process_1*")) and len(list(run.glob("*.log"))) == 1
    record, in_slurm = scores(run)
    assert record["status"] == "completed" and record["devices"] == 2 and record["steps"] == 12
    # the same command outside SLURM: Lightning starts the second rank itself
    alone = run_app(tmp_path, *COMMAND, f"hydra.run.dir={tmp_path / 'alone'}", f"data.cache_dir={tiny_cache}")
    assert alone.returncode == 0, alone.stderr[-2000:]
    _, outside = scores(tmp_path / "alone")
    assert outside.keys() == in_slurm.keys()
    np.testing.assert_allclose([in_slurm[k] for k in outside], [outside[k] for k in outside], rtol=1e-6)
