"""hybrid-sysid plugins: an objective (objectives.py) and a network (networks.py), with their configs (conf/)."""
