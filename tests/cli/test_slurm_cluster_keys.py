"""launcher=slurm's cluster keys: the account, the QOS, the array's throttle and the setup lines compose as
overrides (and from local/launcher/slurm.yaml), and reach the batch script sbatch receives. sbatch here is a
stand-in on PATH that keeps the script and answers as sbatch does (srun beside it, which submitit looks for), so
no cluster is needed; the script's flags are checked against sbatch's own spelling (--account=, --qos=,
--array=0-N%P), the setup lines before the job's srun."""

import os
import stat
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from hybrid_sysid.config import CONF_DIR

pytest.importorskip("hydra_plugins.hydra_submitit_launcher")

SETUP = ["module load python/3.11", "source /shared/venvs/hs/bin/activate"]
CLUSTER = [
    "launcher=slurm",
    "hydra.launcher.account=mylab",
    "hydra.launcher.qos=normal",
    "hydra.launcher.array_parallelism=2",
    f"hydra.launcher.setup=[{', '.join(SETUP)}]",
]


def composed(*overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides), return_hydra_config=True)


def test_the_preset_exposes_the_cluster_keys_at_sbatch_s_defaults():
    launcher = composed("launcher=slurm").hydra.launcher
    assert launcher.account is None and launcher.qos is None  # sbatch's defaults: the user's account, its QOS
    assert launcher.array_parallelism == 256 and list(launcher.setup) == []
    chosen = composed(*CLUSTER).hydra.launcher
    assert (chosen.account, chosen.qos, chosen.array_parallelism, list(chosen.setup)) == ("mylab", "normal", 2, SETUP)


def job(*args):  # what a job would run; never called here
    return args


def test_the_cluster_keys_reach_the_batch_script(tmp_path, monkeypatch):
    from hydra.core.utils import JobReturn

    from hybrid_sysid.launch.slurm import SlurmLauncher

    bin_dir, kept = tmp_path / "bin", tmp_path / "script.sh"
    bin_dir.mkdir()
    sbatch = bin_dir / "sbatch"
    sbatch.write_text(f'#!/bin/sh\ncp "$1" {kept}\necho "Submitted batch job 4242"\n')
    sbatch.chmod(sbatch.stat().st_mode | stat.S_IXUSR)
    srun = bin_dir / "srun"  # submitit takes a machine without srun for no cluster and refuses to submit; never run
    srun.write_text("#!/bin/sh\nexit 1\n")
    srun.chmod(srun.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setattr(SlurmLauncher, "_wait", lambda self, jobs, *a: [JobReturn() for _ in jobs])

    cfg = composed(*CLUSTER, "data=tiny", f"hydra.sweep.dir={tmp_path / 'sweep'}", "hydra.job.name=hs")
    params = OmegaConf.to_container(cfg.hydra.launcher, resolve=True)
    params.pop("_target_")
    launcher = SlurmLauncher(**params)
    launcher.setup(hydra_context=None, task_function=job, config=cfg)
    launcher.launch([["seed=0"], ["seed=1"], ["seed=2"]], initial_job_idx=0)

    lines = Path(kept).read_text().splitlines()
    flags = [line.removeprefix("#SBATCH ") for line in lines if line.startswith("#SBATCH ")]
    assert {"--account=mylab", "--qos=normal", "--array=0-2%2"} <= set(flags), flags
    first_srun = next(i for i, line in enumerate(lines) if line.startswith("srun "))
    assert [lines.index(s) for s in SETUP] == sorted(lines.index(s) for s in SETUP)  # in the order given
    assert all(lines.index(s) < first_srun for s in SETUP)  # before the job starts


def test_a_machine_s_cluster_settings_come_from_local_launcher_slurm(tmp_path, monkeypatch):
    """The account and setup lines of one machine, in the user's local/launcher/slurm.yaml, as if given on the
    command line; the command line still wins."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    local = tmp_path / "hybrid-sysid" / "local" / "launcher" / "slurm.yaml"
    local.parent.mkdir(parents=True)
    local.write_text(OmegaConf.to_yaml({"hydra": {"launcher": {"account": "mylab", "setup": SETUP}}}))
    if (Path(CONF_DIR) / "local").exists():
        pytest.skip("this clone has its own conf/local/, which Hydra's search path finds first")
    launcher = composed("launcher=slurm").hydra.launcher
    assert launcher.account == "mylab" and list(launcher.setup) == SETUP
    assert composed("launcher=slurm", "hydra.launcher.account=other").hydra.launcher.account == "other"
