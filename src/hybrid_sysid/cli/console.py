"""The old path of what cli/predict.py imports, until it imports hybrid_sysid.launch.console itself."""

from hybrid_sysid.launch.console import tolerant_streams  # noqa: F401
