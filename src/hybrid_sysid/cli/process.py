"""The old path of what cli/evaluate.py imports, until it imports hybrid_sysid.launch.process itself."""

from hybrid_sysid.launch.process import console_main, fail  # noqa: F401
