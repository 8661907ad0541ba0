"""launcher=slurm on a real single-node SLURM cluster (scripts/slurm/setup.sh: slurmctld, slurmd, munge, slurmdbd).
Marked ``slurm``, so not in the default run: ``pytest -m slurm tests/slurm`` (about 8 minutes; as root on Debian,
the cluster is set up first when sbatch is missing). What SLURM itself says (sacct, squeue) is the reference:
the jobs ran as SLURM jobs, were requeued, were cancelled."""

import json
import os
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

from helpers.app_process import launch, run_app
from helpers.slurm_accounting import settled

pytestmark = [pytest.mark.slurm, pytest.mark.integration]
SETUP = Path(__file__).resolve().parents[2] / "scripts" / "slurm" / "setup.sh"
QUIET = ["hydra.launcher.timeout_min=10", "trainer.threads=1"]  # two 1-CPU jobs at once on a 2-core node
# tiny data for about 40 s on one thread, a checkpoint every 25 steps
LONG = ["data=tiny", "trainer.max_steps=1500", "trainer.eval_every_n_steps=25", "trainer.curve_every_n_steps=null"]


def cluster_up() -> bool:
    if shutil.which("sbatch") is None:
        return False
    return subprocess.run(["scontrol", "ping"], capture_output=True).returncode == 0


@pytest.fixture(scope="module", autouse=True)
def cluster():
    """The cluster, set up here where it is missing and this is a root Debian machine; else the test skips."""
    if cluster_up():
        return
    if shutil.which("apt-get") is None:
        pytest.skip("no sbatch on PATH, and no apt-get to install SLURM (scripts/slurm/setup.sh is for Debian)")
    if os.geteuid() != 0:
        pytest.skip("no sbatch on PATH, and not root: scripts/slurm/setup.sh needs root for apt-get")
    done = subprocess.run(["bash", str(SETUP)], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0 and cluster_up(), done.stderr[-2000:]


@pytest.fixture(autouse=True)
def no_job_left(tmp_path):
    """A test that fails midway leaves none of its jobs (those submitted from its directory) to the next."""
    yield
    out = subprocess.run(["squeue", "-h", "-o", "%A|%Z"], capture_output=True, text=True).stdout
    left = [job for job, _, folder in (line.partition("|") for line in out.splitlines()) if folder == str(tmp_path)]
    if left:
        subprocess.run(["scancel", *left])


def sacct_states(array: str) -> list[str]:
    """Every state SLURM's accounting holds for the array's jobs, requeued attempts included (-D), once settled
    (accounting lags a job's end: helpers/slurm_accounting.py)."""
    return [state for _, state in settled(array, all_attempts=True)]


def array_of(text: str) -> str:
    found = re.search(r"SLURM job (?:array )?(\d+): \d+ jobs? submitted", text)
    assert found, text[-2000:]
    return found.group(1)


def record(run: Path) -> dict:
    return json.loads((run / "metrics.json").read_text())


def in_queue(array: str) -> bool:
    out = subprocess.run(["squeue", "-h", "-j", array, "-o", "%T"], capture_output=True, text=True).stdout
    return any(state in out for state in ("PENDING", "RUNNING", "COMPLETING", "REQUEUED"))


def wait_for(condition, seconds: float, what: str) -> None:
    deadline = time.time() + seconds
    while not condition():
        assert time.time() < deadline, f"{what} did not happen within {seconds} s"
        time.sleep(1)


def job_of(sweep: Path, num: int = 0) -> str:
    """The SLURM job id of the sweep's job ``num`` ("12_0"), from submitit's folder for it."""
    names = [p.name for p in (sweep / ".submitit").iterdir() if p.is_dir()]
    return next((n for n in names if n.endswith(f"_{num}")), names[0])  # a single job is no array: "12"


def job_logs(sweep: Path) -> str:
    return "".join(p.read_text(errors="replace") for p in (sweep / ".submitit").glob("*/*.out"))


def test_two_job_sweep_runs_as_a_job_array_and_tabulates(tmp_path, tiny_cache):
    sweep = tmp_path / "sw"
    proc = run_app(
        tmp_path, "-m", "launcher=slurm", "debug=fast", "seed=0,1", *QUIET, f"hydra.sweep.dir={sweep}", cache=tiny_cache
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    array = array_of(proc.stdout)
    assert sacct_states(array) == ["COMPLETED", "COMPLETED"]
    assert [record(sweep / str(i))["status"] for i in (0, 1)] == ["completed", "completed"]
    assert (sweep / "summary.md").exists() and "mean relative deviation on the test split" in proc.stdout
    # accounting on: submitit's fallback warning never shows; srun is on PATH, and the jobs do use it
    everything = proc.stdout + proc.stderr + job_logs(sweep)
    assert "Bypassing" not in everything and "srun` command is available" not in everything


def test_request_above_the_partition_is_one_line_and_submits_nothing(tmp_path):
    cpus = os.cpu_count() + 6
    proc = run_app(
        tmp_path,
        "-m",
        "launcher=slurm",
        "debug=fast",
        f"trainer.threads={cpus}",
        f"hydra.sweep.dir={tmp_path / 'sw'}",
        timeout=120,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"error: hydra.launcher.cpus_per_task = {cpus} is not allowed: a job asks {cpus} CPUs")
    assert f"allows {os.cpu_count()} CPUs" in lines[0]
    assert not (tmp_path / "sw").exists()


def test_scancel_then_rerun_resumes_from_last_checkpoint(tmp_path, tiny_cache):
    sweep = tmp_path / "sw"
    args = ["-m", "launcher=slurm", "seed=0", *LONG, *QUIET, f"hydra.sweep.dir={sweep}"]
    proc = launch(tmp_path, *args, cache=tiny_cache)
    last = sweep / "0" / "checkpoints" / "last.ckpt"
    wait_for(last.exists, 240, "a first checkpoint")
    subprocess.run(["scancel", job_of(sweep)], check=True)
    out, _ = proc.communicate(timeout=240)
    assert proc.returncode != 0, out[-2000:]
    assert record(sweep / "0")["status"] == "interrupted"
    assert "CANCELLED" in sacct_states(array_of(out))

    again = run_app(tmp_path, *args, cache=tiny_cache, timeout=600)
    assert again.returncode == 0, again.stdout[-2000:] + again.stderr[-2000:]
    assert record(sweep / "0")["status"] == "completed"
    assert re.search(r"resuming from \S*last\.ckpt", (sweep / "0" / "train.log").read_text())


def test_sigterm_on_the_sweep_cancels_its_jobs(tmp_path, tiny_cache):
    sweep = tmp_path / "sw"
    proc = launch(
        tmp_path, "-m", "launcher=slurm", "seed=0,1", *LONG, *QUIET, f"hydra.sweep.dir={sweep}", cache=tiny_cache
    )
    wait_for(lambda: (sweep / "0" / "checkpoints" / "last.ckpt").exists(), 240, "a first checkpoint")
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=240)
    assert proc.returncode == 128 + signal.SIGTERM, out[-2000:]
    array = array_of(out)
    assert f"SLURM job {array} cancelled" in out
    assert not in_queue(array)
    assert "CANCELLED" in sacct_states(array)
    assert record(sweep / "0")["status"] == "interrupted"


def test_a_job_killed_without_a_result_is_recorded_failed_and_the_sweep_ends(tmp_path, tiny_cache):
    sweep = tmp_path / "sw"
    args = ["-m", "launcher=slurm", "seed=0", *LONG, *QUIET, f"hydra.sweep.dir={sweep}"]
    proc = launch(tmp_path, *args, cache=tiny_cache)
    wait_for(lambda: (sweep / "0" / "checkpoints" / "last.ckpt").exists(), 240, "a first checkpoint")
    # the job's python killed as the OOM killer would: no handler runs, no result is written (srun's own command
    # line names the same module, so the pattern is anchored at the interpreter)
    found = subprocess.run(
        ["pgrep", "-f", f"^\\S*python\\S* .*submitit.core._submit {sweep}"], capture_output=True, text=True
    )
    pids = [int(pid) for pid in found.stdout.split()]
    assert len(pids) == 1, found
    os.kill(pids[0], signal.SIGKILL)
    out, _ = proc.communicate(timeout=240)
    assert proc.returncode == 1, out[-2000:]
    assert record(sweep / "0")["status"] == "failed" and "without a result" in record(sweep / "0")["error"]
    assert "1 of 1 job failed" in out


def test_time_limit_requeues_and_resumes(tmp_path, tiny_cache):
    # SLURM sends the time-limit signal in its 30 s checks, from 30 + 30 s before the two-minute limit: 60 to 90 s
    # into each attempt. The run trains for 90 s whatever the machine's speed (Lightning's max_time, whose clock
    # the checkpoint carries), so the first attempt is always stopped and the second always completes it: it
    # records itself interrupted, is requeued (SLURM holds it about 2 min) and resumes from the last checkpoint
    sweep = tmp_path / "sw"
    proc = run_app(
        tmp_path,
        "-m",
        "launcher=slurm",
        "seed=0",
        *LONG,
        "trainer.max_steps=1000000",
        "+trainer.extra.max_time='00:00:01:30'",
        "trainer.threads=1",
        "hydra.launcher.timeout_min=2",
        "hydra.launcher.signal_delay_s=30",
        f"hydra.sweep.dir={sweep}",
        cache=tiny_cache,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    states = sacct_states(array_of(proc.stdout))
    assert "REQUEUED" in states and states[-1] == "COMPLETED", states
    log = (sweep / "0" / "train.log").read_text()
    assert "SLURM's time limit" in log and re.search(r"resuming from \S*last\.ckpt", log)
    assert record(sweep / "0")["status"] == "completed"


def test_search_trials_run_on_slurm(tmp_path, tiny_cache):
    pytest.importorskip("optuna")
    sweep = tmp_path / "search"
    proc = run_app(
        tmp_path,
        "hparams_search=fast_cnn",
        "debug=fast",
        "launcher=slurm",
        "hydra.sweeper.n_jobs=2",
        *QUIET,
        f"hydra.sweep.dir={sweep}",
        cache=tiny_cache,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    arrays = re.findall(r"SLURM job (?:array )?(\d+): \d+ jobs? submitted", proc.stdout)
    assert len(arrays) == 2  # three trials, two at a time
    assert [s for a in arrays for s in sacct_states(a)] == ["COMPLETED"] * 3
    results = (sweep / "optimization_results.yaml").read_text()
    assert "completed: 3" in results
