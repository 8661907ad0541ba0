"""hybrid-sysid plugins: an objective (objectives.py), a network (networks.py) and a data module (datasets.py), with
their configs (conf/). Hydra imports this package to read the configs: it imports nothing."""
