"""Where a command writes (conf/paths, data.cache_dir): each a path that names a directory. An empty one would
move the writes elsewhere without a word: ``paths.root=''`` makes the runs ``/runs`` at the filesystem's root,
and an empty HYBRID_SYSID_CACHE makes the cache the working directory itself."""

from __future__ import annotations

import os

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.core.checks import bad

CACHE_VARIABLE = "HYBRID_SYSID_CACHE"  # conf/paths/default.yaml: the cache's directory, when set
PATH_KEYS = ("root", "runs_dir", "multirun_dir", "evals_dir", "cache_dir", "trackers_dir")


def check_paths(cfg: DictConfig) -> None:
    """Each of paths.* and data.cache_dir, as given and as resolved, is a path that is not empty. ``paths.root``
    is checked first: the others are under it by default, so the line names what the user gave."""
    keys = [f"paths.{k}" for k in PATH_KEYS if OmegaConf.select(cfg, f"paths.{k}", default=None) is not None]
    if OmegaConf.select(cfg, "data.cache_dir", default=None) is not None:
        keys.append("data.cache_dir")
    for key in keys:
        _check_path(cfg, key)


def _check_path(cfg: DictConfig, key: str) -> None:
    given = OmegaConf.select(cfg, key, throw_on_resolution_failure=False)
    raw = OmegaConf.to_container(cfg, resolve=False)
    for part in key.split("."):
        raw = raw.get(part) if isinstance(raw, dict) else None
    if given is None and raw is not None:  # an interpolation that does not resolve: the read names it
        return
    for value in (raw, given):
        if isinstance(value, str) and not value.strip():
            bad(key, value, _empty_allowed(raw))
        if value is not None and not isinstance(value, str):
            bad(key, value, "a directory's path")


def _empty_allowed(raw) -> str:
    """What an empty path may be instead; an empty HYBRID_SYSID_CACHE names the variable, its origin."""
    if isinstance(raw, str) and CACHE_VARIABLE in raw and os.environ.get(CACHE_VARIABLE) == "":
        return f"a directory's path; the {CACHE_VARIABLE} variable is set but empty: unset it or name a directory"
    return "a directory's path, not empty (. for the working directory)"
