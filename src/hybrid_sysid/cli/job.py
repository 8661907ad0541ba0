"""The old path of what cli/evaluate.py imports, until it imports hybrid_sysid.launch.job itself."""

from hybrid_sysid.launch.job import Preflight, checks_complete, draws_figures, run_job  # noqa: F401
