"""Hydra callback that ends every sweep with its comparison table.

Hydra skips on_multirun_end when a job raised, and with the joblib launcher job callbacks run in worker
processes; so jobs record their own failure and return normally (see train.main), and the summary here is
built from the run records on disk alone. A sweep with a failed job still exits non-zero.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

log = logging.getLogger("hybrid_sysid")


class SweepSummary(Callback):
    def __init__(self, split: str = "test", metric: str = "mean_rel_dev"):
        self.split, self.metric = split, metric

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        from hybrid_sysid.evaluation.summary import to_markdown, write_summary

        sweep_dir = Path(config.hydra.sweep.dir)
        df, table = write_summary(sweep_dir, split=self.split, metric=self.metric)
        print(f"\n{self.metric} on the {self.split} split [%], mean ± std over seeds ({sweep_dir}):\n")
        print(to_markdown(table))
        failed = df[df.status != "completed"].drop_duplicates("run")
        if len(failed):
            for _, row in failed.iterrows():
                log.error("job %s %s: %s", row["run"], row["status"], row["error"])
            raise SystemExit(f"{len(failed)} of {df.run.nunique()} jobs failed; summary in {sweep_dir}")
