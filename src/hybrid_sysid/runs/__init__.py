"""Run and sweep directories, read and written here alone: their file names (layout), a run's files and its record
(rundir: RunDir), resuming it (resume), the one-writer lock (locks), a sweep's record of itself
(sweepdir) and what made a run's numbers (provenance: the commit and the CPU)."""

from omegaconf import OmegaConf


def hydra_subdir(output_dir: str | None) -> str | None:
    """``${hydra_subdir:${hydra.runtime.output_dir}}``, Hydra's output_subdir (conf/config.yaml, conf/eval.yaml):
    .hydra, where Hydra saves a job's config as the job starts, but None, so Hydra saves nothing, in a directory
    holding a completed run. Its saved config belongs to its record and is never replaced: a re-run of it is
    skipped or refused (launch.job), after Hydra would already have rewritten it. Registered here, where records are
    read: every command imports this layer before Hydra starts a job."""
    from hybrid_sysid.runs.rundir import RunDir  # deferred

    return None if output_dir and RunDir(output_dir).completed_record() is not None else ".hydra"


OmegaConf.register_new_resolver("hydra_subdir", hydra_subdir, replace=True)
