"""A saved config read from a run directory is data, which may come from someone else: nothing in it reads this
machine's environment or files, and nothing in it says where this machine writes.

``as_data`` replaces its ``paths`` section and its ``data.cache_dir`` by this machine's (the schema's defaults,
which a command's own overrides then change), and refuses any interpolation through a resolver other than those
that read the config alone. ``${oc.env:...}`` would be resolved on first access, and an error then would echo the
variable's value; a received cache or output path would be written to by eval, predict or init_from. Its
``data.path`` and ``data.labels`` (a user's recordings: files of the machine it ran on) become values that read no
file, until a command names the files again.
"""

from __future__ import annotations

from antlr4.tree.Tree import TerminalNode
from omegaconf import DictConfig, OmegaConf, grammar_parser
from omegaconf.grammar.gen.OmegaConfGrammarParser import OmegaConfGrammarParser as Parser

from hybrid_sysid.config.schema import PathsConfig
from hybrid_sysid.data.recordings_files import UNNAMED

# resolvers that read the config alone (hybrid_sysid.config.resolvers, and OmegaConf's oc.select); every other one
# may read the environment (oc.env), a file or a record (hydra_subdir), Hydra's state (hydra), or build config
# from text (oc.decode, oc.create)
PURE_RESOLVERS = ("p_prior", "fault_fix", "first_set", "slurm_mem_gb", "oc.select")
LOCAL = "paths"  # the section this machine's config gives, never the received one


class NotData(ValueError):
    """A received config holds an interpolation it may not: the text names the key and the resolver, never the
    value."""


def as_data(cfg: DictConfig) -> DictConfig:
    """``cfg`` with this machine's paths and cache directory in place of the received ones, once every other
    interpolation in it goes through PURE_RESOLVERS alone; NotData otherwise. Nothing is resolved here."""
    if LOCAL in cfg:
        cfg[LOCAL] = OmegaConf.to_container(OmegaConf.structured(PathsConfig))
    if isinstance(cfg.get("data", None), DictConfig) and "cache_dir" in cfg.data:
        cfg.data.cache_dir = "${paths.cache_dir}"  # this machine's cache: a received one is never written to
    if isinstance(cfg.get("data", None), DictConfig) and cfg.data.get("path") is not None:
        cfg.data.path, cfg.data.labels = UNNAMED, None  # eval refuses it until data.path is given again
    for where, text in _strings(OmegaConf.to_container(cfg, resolve=False)):
        if where.split(".")[0] == LOCAL or "${" not in text:
            continue
        name = _impure_resolver(text)
        if name is not None:
            raise NotData(
                f"{where} holds an interpolation through {name}, which a received config may not use: only "
                f"{', '.join(PURE_RESOLVERS)}, which read the config alone"
            )
    return cfg


def _strings(node, where: str = ""):
    """(dotted key, text) of every string value, and of every key, at any depth, without recursion."""
    stack = [(where, node)]
    while stack:
        where, node = stack.pop()
        if isinstance(node, dict):
            for k, v in node.items():
                inner = f"{where}.{k}" if where else str(k)
                if isinstance(k, str):
                    yield inner, k
                stack.append((inner, v))
        elif isinstance(node, list):
            stack.extend((f"{where}[{i}]", v) for i, v in enumerate(node))
        elif isinstance(node, str):
            yield where, node


def _impure_resolver(text: str) -> str | None:
    """The first resolver in ``text`` outside PURE_RESOLVERS (a name built by an interpolation is one), or
    "a malformed interpolation" when OmegaConf's grammar cannot parse it; None when every one is pure."""
    try:
        tree = grammar_parser.parse(text)
    except Exception:  # noqa: BLE001 - the grammar's errors are several classes
        return "a malformed interpolation"
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, TerminalNode):
            continue
        if isinstance(node, Parser.ResolverNameContext):
            name = node.getText()
            if name not in PURE_RESOLVERS:
                return "a resolver named by an interpolation" if "${" in name else name
        stack.extend(reversed(list(node.getChildren())))  # in reading order: the outer resolver first
    return None
