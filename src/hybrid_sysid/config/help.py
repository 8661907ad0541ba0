"""``hybrid-sysid --help`` in one composition. Hydra's own help path copies its whole config repository for each of
about 150 group lookups: 1 s of CPU, most of the command's time (benchmarks/startup.py). The text is the same: the
app's template (``hydra.help`` in conf/config.yaml) with the config groups listed as Hydra lists them, read from
the sources the composed config names (``hydra.runtime.config_sources``). A command line with other flags or
``hydra.`` keys, a template asking for more than the groups, or any failure is left to Hydra's own help."""

from __future__ import annotations

import os
import string
from importlib import resources

from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.object_type import ObjectType

HELP_FLAGS = ("--help", "-h")
SKIPPED = ("__pycache__", "__init__.py")  # never a group or an option (Hydra's ConfigSource skips them too)


def help_overrides(args: list[str]) -> list[str] | None:
    """The overrides of a plain help request (``--help`` and key=value arguments); None for any other command
    line, which Hydra handles."""
    if not any(a in HELP_FLAGS for a in args):
        return None
    rest = [a for a in args if a not in HELP_FLAGS]
    if any(a.startswith("-") or a.lstrip("+~").startswith("hydra") for a in rest):
        return None
    return rest


def _entries(source: dict, group: str) -> tuple[set[str], set[str]]:
    """(options, sub-groups) of ``group`` in one config source: a .yaml file is an option, a folder a group."""
    options, groups = set(), set()
    if source["schema"] == "structured":
        store = ConfigStore.instance()
        if group and store.get_type(group) != ObjectType.GROUP:
            return options, groups
        for name in store.list(group):
            kind = store.get_type(f"{group}/{name}" if group else name)
            (groups if kind == ObjectType.GROUP else options).add(name.removesuffix(".yaml"))
        return options, groups
    if source["schema"] == "file":
        folder = os.path.join(source["path"], group)
        names = os.listdir(folder) if os.path.isdir(folder) else []
        items = [(n, os.path.isdir(os.path.join(folder, n))) for n in names]
    else:  # pkg: a package's resources
        folder = resources.files(source["path"]).joinpath(group) if group else resources.files(source["path"])
        items = [(p.name, p.is_dir()) for p in folder.iterdir()] if folder.is_dir() else []
    for name, is_dir in items:
        if name in SKIPPED:
            continue
        if is_dir:
            groups.add(name)
        elif name.endswith(".yaml"):
            options.add(name.removesuffix(".yaml"))
    return options, groups


def config_groups(sources) -> dict[str, list[str]]:
    """Every group with at least one option, across the sources, with its options sorted."""
    found: dict[str, list[str]] = {}

    def walk(parent: str) -> None:
        subgroups = set().union(*(_entries(s, parent)[1] for s in sources))
        for sub in sorted(subgroups):
            group = f"{parent}/{sub}" if parent else sub
            entries = [_entries(s, group) for s in sources]
            options = set().union(*(e[0] for e in entries))
            if options:
                found[group] = sorted(options)
            if any(e[1] for e in entries):
                walk(group)

    walk("")
    return found


def quick_help(args: list[str], conf_dir: str, config_name: str) -> str | None:
    """The help text of a plain help request (``help_overrides``); None for any other command line, and where
    this way cannot give Hydra's text (Hydra's help then runs, and reports any error its own way)."""
    overrides = help_overrides(args)
    if overrides is None:
        return None
    try:
        return app_help(conf_dir, config_name, overrides)
    except Exception:  # noqa: BLE001 - a bad override, say: Hydra's help reports it in one line
        return None


def app_help(conf_dir: str, config_name: str, overrides: list[str]) -> str | None:
    """The help text Hydra prints for ``--help`` with these overrides; None when the template needs more than the
    config groups (Hydra's help then runs)."""
    with initialize_config_dir(config_dir=conf_dir, version_base="1.3"):
        cfg = compose(config_name, overrides=overrides, return_hydra_config=True)
    groups = config_groups([dict(s) for s in cfg.hydra.runtime.config_sources])
    listed = "".join(f"{g}: {', '.join(o)}\n" for g, o in sorted(groups.items()) if g.split("/")[0] != "hydra")
    try:
        return string.Template(cfg.hydra.help.template).substitute(APP_CONFIG_GROUPS=listed)
    except (KeyError, ValueError):  # $CONFIG, $FLAGS_HELP or $HYDRA_CONFIG_GROUPS: Hydra's own help has them
        return None
