"""The config: schemas (schema.py), resolvers (resolvers.py), the classes a config may name (targets.py) and the
checks before any work (validation.py, with memory.py).

Importing it registers the schema and the resolvers with Hydra, which composing the app's config needs (the app,
tests, notebooks); it loads no torch.
"""

from hybrid_sysid.config.memory import available_memory, check_memory
from hybrid_sysid.config.resolvers import register
from hybrid_sysid.config.schema import CONF_DIR, Config, EvalConfig, flatten
from hybrid_sysid.config.validation import validate
from hybrid_sysid.core.checks import ConfigError

register()

__all__ = [
    "CONF_DIR",
    "Config",
    "ConfigError",
    "EvalConfig",
    "available_memory",
    "check_memory",
    "flatten",
    "register",
    "validate",
]
