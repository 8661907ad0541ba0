"""Writing a file so that no reader, and no crash, ever sees half of it; reading a received file within limits of
size, type and nesting."""

from __future__ import annotations

import json
import os
import stat
import tempfile
from pathlib import Path
from typing import Callable

import yaml

# errors= of a text file a command writes: under an ASCII locale a path outside ASCII comes from the command line
# and the file system as lone surrogates; they are written back as the path's own bytes (UTF-8 where it was)
ESCAPED = "surrogateescape"


def readable(text: str) -> str:
    """``text`` as a table or figure shows it: lone surrogates (an ASCII locale's bytes outside ASCII) read as the
    UTF-8 they were, any other undecodable byte as U+FFFD; a figure's fonts cannot draw a surrogate."""
    try:
        raw = text.encode("utf-8", ESCAPED)
    except UnicodeEncodeError:  # a surrogate no byte gave (written as \ud800 in a JSON file)
        raw = text.encode("utf-8", "replace")
    return raw.decode("utf-8", "replace")


def write_atomic(path: str | os.PathLike, write: Callable[[Path], object]) -> None:
    """``write(tmp)`` fills a temporary file beside ``path``, which then replaces ``path`` in one rename.

    The temporary name is unique (concurrent writers of one path never share it) and is removed if ``write``
    fails, so an interrupted write leaves the previous file, or none, never a truncated one.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    # mkstemp makes the file private (0600); give it the mode a plain open() would, so a shared cache or
    # run directory stays readable by colleagues
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        write(Path(tmp))
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)


def write_json_atomic(path: Path, payload: dict) -> None:
    write_atomic(path, lambda tmp: tmp.write_text(json.dumps(payload, indent=2) + "\n"))


def write_yaml_atomic(path: Path, payload) -> None:
    """A YAML file (its folder made if missing), as Hydra writes .hydra/config.yaml."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, lambda tmp: tmp.write_text(yaml.safe_dump(payload, sort_keys=False)))


# Reading a file received from someone else (a run directory, a sweep's multirun.yaml): data that may be hostile.
# Each limit is far above what the project writes (a run's config and record are a few kB) and far below what
# hangs a command or fills its memory.
MAX_BYTES = 16 * 2**20
MAX_DEPTH = 64  # nesting of JSON arrays and objects, YAML sequences and mappings
MAX_YAML_NODES = 100_000  # a YAML file's nodes with each alias counted as the whole node it repeats
# a YAML file's scalar text (keys and values, in UTF-8 bytes) with each alias expanded: a run's saved config is about
# 2 kB and a sweep's multirun.yaml about 8 kB, so 1 MiB is over 100 times either. Building a config walks every
# string each alias repeats, so one long scalar aliased many times takes hours (benchmarks/README.md)
MAX_YAML_BYTES = 2**20


class UnreadableFile(ValueError):
    """A received file refused before or while it is parsed: its text says why in a few words."""


def read_text(path: str | os.PathLike, limit: int = MAX_BYTES) -> str:
    """A regular file's text (after symbolic links), at most ``limit`` bytes, as UTF-8. A FIFO, a device (a link
    to /dev/zero), a directory or a larger file is UnreadableFile, without waiting on it or reading past
    ``limit``."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO's open would otherwise wait for a writer
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise UnreadableFile("not a regular file")
    with os.fdopen(fd, "rb") as f:
        data = f.read(limit + 1)  # the size may grow after fstat: never read past the limit
    if len(data) > limit:
        raise UnreadableFile(f"larger than {limit} bytes")
    return data.decode("utf-8")


def read_json(path: str | os.PathLike, limit: int = MAX_BYTES, depth: int = MAX_DEPTH):
    """A received JSON file's data (read_text's limits), nested at most ``depth`` deep."""
    text = read_text(path, limit)
    try:
        data = json.loads(text)
    except RecursionError:
        raise UnreadableFile(f"nested deeper than {depth}") from None
    _check_depth(data, depth)
    return data


def read_yaml_text(path: str | os.PathLike, limit: int = MAX_BYTES) -> str:
    """A received YAML file's text (read_text's limits) once its node graph, composed without building any value,
    is at most MAX_DEPTH deep, MAX_YAML_NODES large and MAX_YAML_BYTES of text with every alias expanded (a
    "billion laughs" of chained aliases is a few lines that expand beyond any memory)."""
    text = read_text(path, limit)
    # libyaml's composer, where PyYAML has it, builds the same node graph far faster (benchmarks/README.md): a
    # report reads a run's config several times
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        root = yaml.compose(text, Loader=loader)
    except RecursionError:
        raise UnreadableFile(f"nested deeper than {MAX_DEPTH}") from None
    except yaml.YAMLError as exc:
        if "maximum nesting depth" in str(exc):  # libyaml's own limit (1000), met before ours
            raise UnreadableFile(f"nested deeper than {MAX_DEPTH}") from None
        raise UnreadableFile(f"{type(exc).__name__}: {' '.join(str(exc).split())}") from None
    if root is not None:
        _check_yaml_size(root)
    return text


def read_yaml(path: str | os.PathLike, limit: int = MAX_BYTES):
    """A received YAML file as plain data (read_yaml_text's limits)."""
    return yaml.safe_load(read_yaml_text(path, limit))


def _children(node) -> list:
    if isinstance(node, dict):
        return list(node.values())
    if isinstance(node, list):
        return node
    return []


def _check_depth(data, depth: int) -> None:
    stack = [(data, 0)]
    while stack:
        node, level = stack.pop()
        if level > depth:
            raise UnreadableFile(f"nested deeper than {depth}")
        stack.extend((child, level + 1) for child in _children(node))


def _check_yaml_size(root) -> None:
    """Nodes and scalar bytes counted as construction would build them (an alias shares its node, counted at
    every use), in post-order without recursion; a node within itself (a recursive alias) is refused."""

    def kids(node):
        if isinstance(node, yaml.MappingNode):
            return [n for pair in node.value for n in pair]
        return list(node.value) if isinstance(node, yaml.SequenceNode) else []

    size, text, open_ = {}, {}, set()
    stack = [(root, 0)]
    while stack:
        node, level = stack.pop()
        if level > MAX_DEPTH:
            raise UnreadableFile(f"nested deeper than {MAX_DEPTH}")
        key = id(node)
        if key in size:
            continue
        if key in open_:  # its children are counted: now itself
            size[key] = 1 + sum(size[id(k)] for k in kids(node))
            if size[key] > MAX_YAML_NODES:
                raise UnreadableFile(f"more than {MAX_YAML_NODES} nodes with its aliases expanded")
            own = len(node.value.encode("utf-8", "surrogatepass")) if isinstance(node, yaml.ScalarNode) else 0
            text[key] = own + sum(text[id(k)] for k in kids(node))
            if text[key] > MAX_YAML_BYTES:
                raise UnreadableFile(f"more than {MAX_YAML_BYTES} bytes of text with its aliases expanded")
            open_.discard(key)
            continue
        open_.add(key)
        stack.append((node, level))
        for child in kids(node):
            if id(child) in open_ and id(child) not in size:
                raise UnreadableFile("an alias within its own anchor")
            stack.append((child, level + 1))
