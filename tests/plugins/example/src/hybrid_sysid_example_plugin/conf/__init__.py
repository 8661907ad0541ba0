# a package, so that Hydra finds the configs here (pkg://hybrid_sysid_example_plugin.conf, declared in pyproject.toml)
