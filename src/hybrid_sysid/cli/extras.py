"""Options that need an optional package: a missing one is one line before any work, with the pip command that
brings it as the user's own install was made (``pip install -e ".[search]"`` in an editable checkout, ``pip
install "hybrid-sysid[search]"`` for a wheel: hybrid_sysid.core.install)."""

from __future__ import annotations

import importlib.util

from hybrid_sysid.core.install import install_command

# an option that needs an optional package -> (the module it needs, the extra that brings it)
EXTRAS = {
    "hparams_search=": ("optuna", "search"),
    "hydra/sweeper=study": ("optuna", "search"),
    "experiment=tuned": ("optuna", "search"),
    "callbacks=rich_progress_bar": ("rich", "rich"),
    "launcher=slurm": ("hydra_plugins.hydra_submitit_launcher", "slurm"),
    "launcher=submitit_local": ("hydra_plugins.hydra_submitit_launcher", "slurm"),
}


def missing_extra(args) -> str | None:
    """A one-line error for the first command-line option whose optional package is not installed (Hydra itself
    would fail on it with a long message on the config search path), else None."""
    for arg in args:
        for prefix, (module, extra) in EXTRAS.items():
            if arg.lstrip("+~").startswith(prefix) and not installed(module):
                name = module.split(".")[-1].replace("_", "-")
                return f"{arg} needs {name}, which is not installed: {install_command(extra)}"
    return None


def installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:  # its parent package is missing
        return False
