"""hybrid-sysid's hyperparameter search as a Hydra sweeper (config: hybrid_sysid/conf/hydra/sweeper/study.yaml).

Hydra accepts a sweeper only from this namespace package, and imports every module here for every Hydra app in
the environment, so this one holds the class alone and imports the work (hybrid_sysid.launch.search, optuna) when a
search runs."""

from __future__ import annotations

from typing import Any

from hydra.plugins.sweeper import Sweeper


class StudySweeper(Sweeper):
    def __init__(self, **settings: Any) -> None:
        self.settings = settings
        self.config = self.launcher = None

    def setup(self, *, hydra_context, task_function, config) -> None:
        from hydra.core.plugins import Plugins

        self.config = config
        self.launcher = Plugins.instance().instantiate_launcher(
            hydra_context=hydra_context, task_function=task_function, config=config
        )

    def sweep(self, arguments: list[str]) -> Any:
        from hybrid_sysid.launch.search import run_study

        return run_study(self.config, self.launcher, self.settings, list(arguments))
