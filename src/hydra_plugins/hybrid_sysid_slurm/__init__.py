"""launcher=slurm's launcher as a Hydra plugin (config: hybrid_sysid/conf/launcher/slurm.yaml).

Hydra accepts a launcher only from this namespace package, and imports every module here for every Hydra app in
the environment, so this one holds the class alone; its work is in hybrid_sysid.launch.slurm. Without
hydra-submitit-launcher (the slurm extra) it defines nothing, and launcher=slurm is refused in one line before
Hydra starts (hybrid_sysid.launch.process)."""

from __future__ import annotations

try:
    from hybrid_sysid.launch.slurm import SlurmLauncher as _SlurmLauncher
except ImportError:  # hydra-submitit-launcher is not installed
    _SlurmLauncher = None

if _SlurmLauncher is not None:

    class SlurmLauncher(_SlurmLauncher):
        """hybrid_sysid.launch.slurm.SlurmLauncher, where Hydra looks for launchers."""
