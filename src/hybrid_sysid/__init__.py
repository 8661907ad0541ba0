"""hybrid-sysid: labelled and physics-informed (hybrid) objectives for identifying a quarter car's seat parameters.

The folders are the layers, each importing only those below it (tests/test_layers.py): ``core`` (errors, value
checks, allowed values, atomic files, stop requests), ``physics`` (plain numpy), ``data`` (dataset spec, cache,
windows, the data module), ``model`` and ``baselines`` (networks, objectives and least squares, behind the
protocols of model/base.py), ``config`` (schema, allowed classes, checks), ``runs`` (run and sweep directories),
``training`` (build, fit, score, trackers), ``report`` (tables and figures from files), ``experiments`` and
``inference`` (chained jobs; a trained run as an estimator, ``load_estimator``), ``cli`` (the commands).
docs/design.md maps each folder.

Every import sits at the top of its module but for those tagged ``# deferred``, which wait until work needs them.
Lightning and torch take seconds of CPU to import, and a command's checks, a refusal or a sweep's parent need
neither. pandas, matplotlib and scipy.stats serve the report's tables and figures alone; numba loads with the
dataset kernel (``hybrid_sysid.data`` names it lazily). The optional extras (optuna, mlflow, tensorboard, submitit)
load where their feature runs, so a missing one fails that feature only. ``hybrid-sysid --help`` and a refusal
before work load none of these (tests/cli/test_light_start.py; benchmarks/startup.py measures them).
"""

__version__ = "0.2.0"


def __getattr__(name):
    # `import hybrid_sysid.physics` runs this file and must stay numpy-only: torch loads only when asked for
    if name == "load_estimator":
        from hybrid_sysid.inference.loading import load_estimator  # deferred

        return load_estimator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
