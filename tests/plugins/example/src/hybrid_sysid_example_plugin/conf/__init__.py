# a package, so that hydra.searchpath=[pkg://hybrid_sysid_example_plugin.conf] finds the configs here
