"""The global rank and the world size read before the trainer exists (hybrid_sysid.core.ranks), against what each
launcher sets: only the global rank 0 writes, and a node count that does not match the launched processes is one
line naming trainer.num_nodes."""

import pytest

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.core.ranks import RANK_VARIABLES, check_world, is_global_zero

LAUNCHER_VARIABLES = (*RANK_VARIABLES, "WORLD_SIZE", "SLURM_NTASKS", "SLURM_JOB_NAME", "MASTER_ADDR")


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
        ({"WORLD_SIZE": "4"}, 2, 2),
        ({"SLURM_NTASKS": "2", "SLURM_JOB_NAME": "train"}, 2, 1),
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
