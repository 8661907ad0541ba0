"""The global rank and the world size read before the trainer exists (hybrid_sysid.core.ranks), against what each
launcher sets: only the global rank 0 writes, and a node count that does not match the launched processes is one
line naming trainer.num_nodes."""

import pytest

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.core.ranks import NODE_VARIABLES, RANK_VARIABLES, check_world, is_global_zero

LAUNCHER_VARIABLES = (*RANK_VARIABLES, *NODE_VARIABLES, "WORLD_SIZE", "SLURM_NTASKS", "SLURM_JOB_NAME")


@pytest.fixture
def env(monkeypatch):
    for name in LAUNCHER_VARIABLES:
        monkeypatch.delenv(name, raising=False)

    def given(**values):
        for name, value in values.items():
            monkeypatch.setenv(name, value)

    return given


@pytest.mark.parametrize(
    "variables, zero",
    [
        ({}, True),  # one process
        ({"LOCAL_RANK": "1", "NODE_RANK": "0", "WORLD_SIZE": "2"}, False),  # the rank Lightning starts on one node
        ({"NODE_RANK": "1", "LOCAL_RANK": "0"}, False),  # node 1's first rank, Lightning's environment
        ({"NODE_RANK": "0", "LOCAL_RANK": "0"}, True),
        ({"RANK": "1", "GROUP_RANK": "1", "LOCAL_RANK": "0"}, False),  # torchrun, second node
        ({"RANK": "0", "GROUP_RANK": "0", "LOCAL_RANK": "0"}, True),
        ({"SLURM_PROCID": "1", "SLURM_NTASKS": "2"}, False),  # srun's second task
        ({"SLURM_PROCID": "0", "SLURM_NTASKS": "2"}, True),
    ],
)
def test_only_the_global_rank_zero_is_zero(env, variables, zero):
    env(**variables)
    assert is_global_zero() is zero


@pytest.mark.parametrize(
    "variables, nodes, devices",
    [
        ({"WORLD_SIZE": "3"}, 1, 2),
        ({"WORLD_SIZE": "2"}, 2, 2),
        ({"SLURM_NTASKS": "2", "SLURM_JOB_NAME": "train"}, 1, 1),
        ({"NODE_RANK": "2", "LOCAL_RANK": "0"}, 2, 1),  # a third node where two were given
        ({}, 2, 1),  # no launcher starts the other node: the process would wait for it for ever
        ({}, 3, 2),
        ({"WORLD_SIZE": "4"}, 2, 2),  # the world of two nodes, but nothing starts node 1's processes
        ({"WORLD_SIZE": "2", "LOCAL_RANK": "0"}, 2, 1),
    ],
)
def test_a_node_count_not_matching_the_launched_processes_names_trainer_num_nodes(env, variables, nodes, devices):
    env(**variables)
    with pytest.raises(ConfigError, match="trainer.num_nodes") as caught:
        check_world(nodes, devices)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize(
    "variables, nodes, devices",
    [
        ({}, 1, 2),  # Lightning starts the ranks itself
        ({"SLURM_NTASKS": "2", "SLURM_JOB_NAME": "train"}, 2, 1),
        ({"SLURM_NTASKS": "4", "SLURM_PROCID": "3", "SLURM_JOB_NAME": "train", "WORLD_SIZE": "4"}, 2, 2),
        # torchrun --nnodes=2 --nproc-per-node=2, a rank of node 1
        ({"WORLD_SIZE": "4", "RANK": "2", "GROUP_RANK": "1", "MASTER_ADDR": "node0", "TORCHELASTIC_RUN_ID": "1"}, 2, 2),
        ({"WORLD_SIZE": "4", "MASTER_ADDR": "10.0.0.1", "NODE_RANK": "0", "LOCAL_RANK": "0"}, 2, 2),  # by hand
        ({"SLURM_NTASKS": "4", "SLURM_JOB_NAME": "interactive"}, 1, 2),  # Lightning ignores an interactive job
        ({"WORLD_SIZE": "8"}, 1, "auto"),  # devices not a count: Lightning's to check
        ({"MASTER_ADDR": "10.0.0.1", "NODE_RANK": "1"}, 2, 1),  # a node started by hand: Lightning's environment
    ],
)
def test_a_matching_node_count_passes(env, variables, nodes, devices):
    env(**variables)
    check_world(nodes, devices)


def test_a_node_count_below_one_is_refused(env):
    with pytest.raises(ConfigError, match="trainer.num_nodes"):
        check_world(0, 1)


def test_a_world_size_with_no_launcher_is_one_line_before_any_directory(env, tmp_path, monkeypatch, cli_in_process):
    """WORLD_SIZE=4 with 2 nodes x 2 devices and nothing that starts node 1: the command once waited in the
    rendezvous for processes nobody started, deaf to SIGTERM, and left a run directory with no record."""
    import hybrid_sysid.cli.train as train

    def waits(*args, **kwargs):  # where the job would wait for node 1 for ever: fail instead of hanging
        pytest.fail("the job ran")

    monkeypatch.setattr(train, "run_task", waits)
    env(WORLD_SIZE="4")
    args = ["data=tiny", "trainer=debug", "trainer.max_steps=2", "trainer.num_nodes=2", "trainer.devices=2"]
    code, out, err = cli_in_process(
        train.main, *args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tmp_path}
    )
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: trainer.num_nodes"), err[-2000:]
    assert "WORLD_SIZE = 4" in lines[0] and "Traceback" not in out + err
    assert list(tmp_path.iterdir()) == []
