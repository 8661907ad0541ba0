"""This machine's settings for an installed hybrid-sysid: the user's config folder on Hydra's search path.

conf/config.yaml loads the optional group ``local`` (``local/default.yaml``, and ``local/launcher/<launcher>.yaml``
with the chosen launcher's settings), as lightning-hydra-template loads its git-ignored ``configs/local/``. In a
clone it lies in the package's own conf/local/ (git-ignored). An installed package's conf/ sits in site-packages,
where a file would be lost at the next upgrade and shared by every user of the environment. So this plugin adds
``$XDG_CONFIG_HOME/hybrid-sysid`` (``~/.config/hybrid-sysid``) after the package's own configs, when that folder
exists, for hybrid-sysid's apps alone: Hydra imports every module here for every Hydra app in the environment.
"""

from __future__ import annotations

import os
from pathlib import Path

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin

APP = "hybrid-sysid"  # the folder's name under the user's config home


def user_config_dir() -> Path | None:
    """``$XDG_CONFIG_HOME/hybrid-sysid``, ``~/.config/hybrid-sysid`` without the variable; None without a home."""
    base = os.environ.get("XDG_CONFIG_HOME")
    if not base:
        try:
            base = str(Path.home() / ".config")
        except RuntimeError:  # no HOME and no password entry: no user folder
            return None
    return Path(base) / APP


def _is_ours(path: str) -> bool:
    """A search path element holding hybrid-sysid's own configs (file://.../hybrid_sysid/conf, pkg://...)."""
    if path.startswith("pkg://"):
        return path.removeprefix("pkg://").rstrip("/") == "hybrid_sysid.conf"
    return Path(path.removeprefix("file://")).parts[-2:] == ("hybrid_sysid", "conf")


class LocalConfigSearchPath(SearchPathPlugin):
    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        folder = user_config_dir()
        if folder is None or not folder.is_dir():
            return
        if any(_is_ours(element.path) for element in search_path.get_path()):
            search_path.append(provider="hybrid-sysid-local", path=f"file://{folder}")
