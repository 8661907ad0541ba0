"""Hydra callback that ends every sweep with its comparison table.

Hydra skips on_multirun_end when a job raised, and with the joblib launcher job callbacks run in worker
processes; so jobs record their own failure and return normally (see hybrid_sysid.app), and the summary here is
built from the run records on disk alone. A sweep with a failed job still exits non-zero.

Options (set under hydra.callbacks.sweep_summary in an experiment file, e.g. conf/experiment/paper.yaml):
``reproduction: true`` also writes reproduction.md (the paper's figures beside ours); ``latex: true`` also
writes summary.tex.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from hybrid_sysid.report.paper import write_reproduction
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import to_markdown

log = logging.getLogger("hybrid_sysid")


class SweepSummary(Callback):
    def __init__(self, split: str = "test", metric: str = "mean_rel_dev", reproduction: bool = False,
                 latex: bool = False):
        self.split, self.metric, self.reproduction, self.latex = split, metric, reproduction, latex

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        df, table = write_summary(sweep_dir, split=self.split, metric=self.metric, latex=self.latex)
        print(f"\n{self.metric} on the {self.split} split [%], mean ± std over seeds ({sweep_dir}):\n")
        print(to_markdown(table))
        if self.reproduction:
            print(write_reproduction(sweep_dir))
            print(f"(written to {sweep_dir / 'reproduction.md'})")
        failed = df[df.status != "completed"].drop_duplicates("run")
        if len(failed):
            for _, row in failed.iterrows():
                log.error("job %s %s: %s", row["run"], row["status"], row["error"])
            raise SystemExit(f"{len(failed)} of {df.run.nunique()} jobs failed; summary in {sweep_dir}")
