"""Installed plugins' configs on hybrid-sysid's search path, so ``model=tiny_net`` needs no ``hydra.searchpath``.

A package declares the package of its configs by an entry point of the group hybrid_sysid.configs (``mylab =
"mylab.conf"``; docs/extending.md); hybrid_sysid.config.plugins reads them from the installed packages' metadata.
Hydra imports every module here for every Hydra app in the environment, so this one holds the class alone and acts
only where hybrid-sysid's configs are on the search path: its apps import hybrid_sysid.config before they compose
(it registers the schema and the resolvers), and another app's search path never holds its conf/. With no plugin
installed it adds nothing.
"""

from __future__ import annotations

import sys

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin


class PluginConfigsSearchPath(SearchPathPlugin):
    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        if "hybrid_sysid.config" not in sys.modules:  # not hybrid-sysid's app: import nothing of it
            return
        from hybrid_sysid.config.plugins import searchpath

        for provider, path in searchpath([element.path for element in search_path.get_path()]):
            search_path.append(provider=provider, path=path)
