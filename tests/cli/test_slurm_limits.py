"""launcher=slurm without a cluster: the preset's request (CPUs from trainer.threads, memory from the data's size),
the partition's limits and pending reasons read from SLURM's own text (captured from slurm-wlm 22.05), and no
srun hint outside a SLURM job."""

import math
import warnings

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.launch import slurm_limits as sl

pytest.importorskip("hydra_plugins.hydra_submitit_launcher")

# `scontrol show partition debug -o` after `scontrol update PartitionName=debug MaxTime=1 MaxCPUsPerNode=1
# MaxMemPerNode=4000`, and as scripts/slurm/setup.sh leaves it
LIMITED = (
    "PartitionName=debug AllowGroups=ALL AllowAccounts=ALL AllowQos=ALL AllocNodes=ALL Default=YES QoS=N/A "
    "DefaultTime=NONE DisableRootJobs=NO ExclusiveUser=NO GraceTime=0 Hidden=NO MaxNodes=UNLIMITED MaxTime=00:01:00 "
    "MinNodes=0 LLN=NO MaxCPUsPerNode=1 Nodes=vm PriorityJobFactor=1 PriorityTier=1 RootOnly=NO ReqResv=NO "
    "OverSubscribe=NO OverTimeLimit=NONE PreemptMode=OFF State=UP TotalCPUs=2 TotalNodes=1 SelectTypeParameters=NONE "
    "JobDefaults=(null) DefMemPerNode=UNLIMITED MaxMemPerNode=4000 TRES=cpu=2,mem=22644M,node=1,billing=2"
)
OPEN = (
    "PartitionName=debug AllowGroups=ALL AllowAccounts=ALL AllowQos=ALL AllocNodes=ALL Default=YES QoS=N/A "
    "DefaultTime=NONE DisableRootJobs=NO ExclusiveUser=NO GraceTime=0 Hidden=NO MaxNodes=UNLIMITED MaxTime=UNLIMITED "
    "MinNodes=0 LLN=NO MaxCPUsPerNode=UNLIMITED Nodes=vm PriorityJobFactor=1 PriorityTier=1 RootOnly=NO ReqResv=NO "
    "OverSubscribe=NO OverTimeLimit=NONE PreemptMode=OFF State=UP TotalCPUs=2 TotalNodes=1 SelectTypeParameters=NONE "
    "JobDefaults=(null) DefMemPerNode=UNLIMITED MaxMemPerNode=UNLIMITED TRES=cpu=2,mem=22644M,node=1,billing=2"
)
NODES = "2 22644\n"  # sinfo -h -N -p debug -o "%c %m"
# squeue -h -r -t all -o "%i|%T|%r" with the limits above: jobs 1 (--time=5), 2 (-c 2), 3 (--array=0-1
# --mem=16G) and 4 (--array=0-1, one CPU each, one of them waiting for the other's CPU)
QUEUE = """1|PENDING|PartitionTimeLimit
2|PENDING|PartitionConfig
3_0|PENDING|MaxMemPerLimit
3_1|PENDING|MaxMemPerLimit
4_1|PENDING|Resources
4_0|RUNNING|None
"""


def test_partition_limits_are_the_node_capped_by_the_partition():
    limited = sl.limits("debug", LIMITED, NODES)
    assert (limited.cpus, limited.mem_mb, limited.minutes, limited.nodes) == (1, 4000, 1, 1)
    open_ = sl.limits("debug", OPEN, NODES)
    assert (open_.cpus, open_.mem_mb, open_.minutes, open_.nodes) == (2, 22644, None, 1)


@pytest.mark.parametrize(
    "text, minutes",
    [
        ("UNLIMITED", None),
        ("infinite", None),
        ("30", 30),
        ("5:00", 5),
        ("5:01", 6),
        ("00:01:00", 1),
        ("2:30:00", 150),
        ("1-00:00:00", 1440),
        ("2-3", 51 * 60),
        ("1-0:30", 1470),
    ],
)
def test_slurm_times_in_minutes(text, minutes):
    assert sl.minutes(text) == minutes


def test_the_issues_request_on_a_small_node_is_one_line_naming_request_and_limit():
    # 4 CPUs and 16 GB a job (the old preset) on a 2-CPU node; then memory alone above a 4000 MB cap; then time
    refusal = sl.too_big(sl.Request(cpus_per_task=4, mem_gb=16, minutes=240), sl.limits("debug", OPEN, NODES))
    assert (refusal.key, refusal.value) == ("hydra.launcher.cpus_per_task", 4)
    assert "a job asks 4 CPUs, but partition debug allows 2 CPUs" in str(refusal) and "\n" not in str(refusal)
    refusal = sl.too_big(sl.Request(cpus_per_task=1, mem_gb=16, minutes=1), sl.limits("debug", LIMITED, NODES))
    assert (refusal.key, refusal.value) == ("hydra.launcher.mem_gb", 16)
    assert "a job asks 16 GB a node, but partition debug allows 1 CPUs and 3.91 GB a node" in str(refusal)
    refusal = sl.too_big(sl.Request(cpus_per_task=1, mem_gb=1, minutes=5), sl.limits("debug", LIMITED, NODES))
    assert (refusal.key, refusal.value) == ("hydra.launcher.timeout_min", 5) and ", 1 min, " in str(refusal)
    # two tasks of 2 CPUs on a node: 4 CPUs a node
    refusal = sl.too_big(sl.Request(2, 3, 60, tasks_per_node=2), sl.limits("debug", OPEN, NODES))
    assert refusal.key == "hydra.launcher.cpus_per_task" and "a job asks 4 CPUs" in str(refusal)
    assert sl.too_big(sl.Request(cpus_per_task=2, mem_gb=3, minutes=60), sl.limits("debug", OPEN, NODES)) is None


def test_pending_reasons_that_never_clear_are_told_from_waiting_for_resources():
    states = sl.queue(QUEUE)
    assert states["3_1"] == ("PENDING", "MaxMemPerLimit") and states["4_0"] == ("RUNNING", "None")
    for job, reason in (("1", "PartitionTimeLimit"), ("2", "PartitionConfig"), ("3_0", "MaxMemPerLimit")):
        assert sl.never_starts({job: states[job]}) == reason
    assert sl.never_starts({j: states[j] for j in ("4_0", "4_1")}) is None  # Resources: it starts after 4_0


def compose_slurm(*overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=["launcher=slurm", *overrides], return_hydra_config=True)
    return OmegaConf.to_container(cfg.hydra.launcher, resolve=True)


def test_preset_asks_the_jobs_threads_and_the_datas_memory():
    launcher = compose_slurm()
    assert launcher["cpus_per_task"] == 2 and launcher["max_num_timeout"] > 0
    # data=default: 40 roads x 50 masses x 1200 steps x 4 channels at 8 bytes = 76.8 MB, plus 2 GB
    assert launcher["mem_gb"] == math.ceil((40 * 50 * 1200 * 4 * 8 + 2 * 40 * 1200 * 8) / 2**30 + 2) == 3
    launcher = compose_slurm("data=paper", "trainer.threads=6")  # 100 x 100 x 6000 x 4 x 8 B = 1.79 GiB
    assert launcher["cpus_per_task"] == 6 and launcher["mem_gb"] == 4
    launcher = compose_slurm("hydra.launcher.mem_gb=12", "hydra.launcher.cpus_per_task=3")
    assert (launcher["mem_gb"], launcher["cpus_per_task"]) == (12, 3)


def test_no_srun_hint_outside_a_slurm_job(tmp_path, monkeypatch):
    import lightning as L

    from hybrid_sysid.launch.console import quiet_libraries

    srun = tmp_path / "srun"
    srun.write_text("#!/bin/sh\nexit 0\n")
    srun.chmod(0o755)
    monkeypatch.setenv("PATH", f"{tmp_path}:/usr/bin:/bin")
    for name in ("SLURM_JOB_ID", "SLURM_NTASKS", "SLURM_JOB_NAME"):
        monkeypatch.delenv(name, raising=False)
    with warnings.catch_warnings(record=True) as before:
        warnings.simplefilter("always")
        L.Trainer(logger=False, enable_progress_bar=False, enable_checkpointing=False)
    assert any("srun" in str(w.message) for w in before)  # Lightning's hint, without the filter
    with warnings.catch_warnings(record=True) as after:
        warnings.simplefilter("always")
        quiet_libraries()
        L.Trainer(logger=False, enable_progress_bar=False, enable_checkpointing=False)
    assert not any("srun" in str(w.message) for w in after)


class FakeJob:
    """What the sweep's wait reads of a submitit job: its id and the paths of its result and log."""

    def __init__(self, job_id, folder):
        self.job_id = job_id
        self.paths = type("Paths", (), {"result_pickle": folder / f"{job_id}_result.pkl", "stderr": folder / "err"})


def fake_slurm(monkeypatch, queue_text):
    """SLURM's commands answering with captured text; scancel recorded, not run."""
    from hybrid_sysid.launch import slurm

    answers = {"squeue": queue_text, "scontrol": OPEN, "sinfo": NODES}
    monkeypatch.setattr(slurm.slurm_limits, "run", lambda *cmd: answers[cmd[0]])
    cancelled = []
    monkeypatch.setattr(slurm.subprocess, "run", lambda cmd, **kw: cancelled.append(cmd))
    return slurm, cancelled


def test_an_array_pending_for_ever_is_cancelled_with_one_line(monkeypatch, tmp_path, capsys):
    # the issue's case: 4 CPUs and 16 GB a job queued on a smaller node, Reason=PartitionConfig
    slurm, cancelled = fake_slurm(monkeypatch, "12_0|PENDING|PartitionConfig\n12_1|PENDING|PartitionConfig\n")
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)  # as a user runs it: the line alone
    launcher = slurm.SlurmLauncher(cpus_per_task=4, mem_gb=16, timeout_min=240, partition="debug")
    jobs = [FakeJob("12_0", tmp_path), FakeJob("12_1", tmp_path)]
    with pytest.raises(SystemExit):
        launcher._poll(jobs, "12", [None, None], {}, [[], []], 0)
    assert cancelled == [["scancel", "12"]]
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "SLURM job 12 cannot start (Reason=PartitionConfig)" in lines[0]
    assert "a job asks 4 CPUs and 16 GB a node, 240 min, 1 node, but partition debug allows 2 CPUs" in lines[0]


def test_a_job_that_ended_without_a_result_stops_the_wait(monkeypatch, tmp_path):
    slurm, cancelled = fake_slurm(monkeypatch, "12_0|FAILED|NonZeroExitCode\n12_1|RUNNING|None\n")
    monkeypatch.setattr(slurm, "GRACE", -1.0)  # its result file would have shown by now
    launcher = slurm.SlurmLauncher(cpus_per_task=1, mem_gb=3, timeout_min=60)
    jobs = [FakeJob(j, tmp_path) for j in ("12_0", "12_1", "12_2")]  # 12_2: no longer listed at all
    results = [None, None, None]
    launcher._poll(jobs, "12", results, {}, [["seed=0"], ["seed=1"], ["seed=2"]], 0)
    assert results[1] is None and not cancelled  # running: still waited for
    assert results[0].return_value["status"] == "failed"
    assert "SLURM job 12_0 ended FAILED without a result" in results[0].return_value["error"]
    assert "SLURM job 12_2 ended GONE" in results[2].return_value["error"]
