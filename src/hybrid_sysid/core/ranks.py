"""Which process of a training of several processes (DDP, on one or several nodes) this one is, read before the
trainer exists from the variables its launcher sets, as Lightning's cluster environments read them: torchrun's
RANK and WORLD_SIZE, SLURM's SLURM_PROCID and SLURM_NTASKS (srun), Lightning's own NODE_RANK and LOCAL_RANK (the
processes Lightning starts, or a user's on each node). Only the global rank 0 writes into the run directory, so
every node may share it; a local rank 0 on a node above 0 is not global rank 0."""

from __future__ import annotations

import os

from hybrid_sysid.core.checks import bad, check_int

# every variable that names a rank: the global rank is 0 only if each one set is 0 (torchrun sets RANK, GROUP_RANK
# and LOCAL_RANK; srun SLURM_PROCID; Lightning's environment NODE_RANK and LOCAL_RANK, its global rank being
# NODE_RANK x devices + LOCAL_RANK)
RANK_VARIABLES = ("RANK", "SLURM_PROCID", "NODE_RANK", "GROUP_RANK", "LOCAL_RANK")
# what a process started as one node of several holds: Lightning's environment started by hand on each node
# (MASTER_ADDR, NODE_RANK), torchrun (MASTER_ADDR, GROUP_RANK, TORCHELASTIC_RUN_ID). WORLD_SIZE is not among them:
# alone it says how many processes to wait for, not that anything starts them on the other nodes
NODE_VARIABLES = ("MASTER_ADDR", "NODE_RANK", "GROUP_RANK", "TORCHELASTIC_RUN_ID")


def is_global_zero() -> bool:
    """Whether this process is the global rank 0 (or the only process): the one that locks and writes the run."""
    return all(os.environ.get(name, "0").strip() in ("", "0") for name in RANK_VARIABLES)


def launched_world() -> tuple[int, str] | None:
    """The number of processes the launcher started and the variable that says so: WORLD_SIZE (torchrun, or the
    ranks Lightning starts), else SLURM_NTASKS in a batch job (Lightning's SLURM environment, which an interactive
    job named bash or interactive does not use); None when nothing says (one process, or Lightning starts them)."""
    if os.environ.get("WORLD_SIZE", "").strip().isdigit():
        return int(os.environ["WORLD_SIZE"]), "WORLD_SIZE"
    tasks = slurm_tasks()
    return None if tasks is None else (tasks, "SLURM_NTASKS")


def slurm_tasks() -> int | None:
    """The tasks srun started in a SLURM batch job (Lightning's SLURM environment), None outside one."""
    tasks = os.environ.get("SLURM_NTASKS", "").strip()
    if tasks.isdigit() and os.environ.get("SLURM_JOB_NAME") not in ("bash", "interactive"):
        return int(tasks)
    return None


def starts_other_nodes() -> bool:
    """Whether a launcher started this process as one node of several: srun in a batch job, torchrun, or a user
    who set MASTER_ADDR or NODE_RANK on each node. A WORLD_SIZE alone does not say so."""
    return slurm_tasks() is not None or any(os.environ.get(v, "").strip() for v in NODE_VARIABLES)


def check_world(num_nodes, devices) -> None:
    """trainer.num_nodes x trainer.devices is the world size the launcher started, and a node's rank is below
    trainer.num_nodes; else ConfigError naming trainer.num_nodes (the processes would wait for each other in the
    rendezvous until its timeout). Devices not given as a count (auto, a list) are Lightning's to check."""
    nodes = check_int("trainer.num_nodes", num_nodes, 1)
    node = os.environ.get("NODE_RANK", os.environ.get("GROUP_RANK", "")).strip()
    if node.isdigit() and int(node) >= nodes:
        bad("trainer.num_nodes", nodes, f"more than this node's rank, NODE_RANK = {node} (one rank per node, from 0)")
    world = launched_world()
    if nodes > 1 and not starts_other_nodes():
        # nothing starts the other nodes' processes: this one would wait for them in the rendezvous, deaf to signals.
        # A WORLD_SIZE that matches (4 for 2 nodes x 2 devices) changes nothing: no process of node 1 ever comes
        given = "" if world is None else f", {world[1]} = {world[0]} alone starts none"
        bad(
            "trainer.num_nodes",
            nodes,
            "1 unless a launcher starts a process on every node (launcher=slurm, srun, torchrun; or by hand, with "
            f"MASTER_ADDR and NODE_RANK set on each node){given}",
        )
    if world is None or isinstance(devices, bool) or not isinstance(devices, int):
        return
    size, source = world
    if nodes * devices != size:
        bad(
            "trainer.num_nodes",
            nodes,
            f"trainer.num_nodes x trainer.devices must equal the processes the launcher started, {source} = {size} "
            f"(here {nodes} x {devices} = {nodes * devices})",
        )
