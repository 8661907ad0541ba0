"""Hydra callback that ends every sweep with its comparison table.

Hydra skips on_multirun_end when a job raised, and with the joblib launcher job callbacks run in worker
processes; so jobs record their own failure and return normally (see hybrid_sysid.app), and the summary here is
built from the run records on disk alone. A sweep with a failed job still exits non-zero.

Options, set under hydra.callbacks.sweep_summary: ``reproduction: true`` (conf/experiment/paper.yaml) also
writes reproduction.md, the paper's figures beside ours; ``compare``: the row key the table's marks compare
(default: objective when swept); ``transfer_figure: true`` (conf/experiment/transfer.yaml) also draws
figures/transfer.png. Other splits, metrics and the LaTeX table are one
``hybrid-sysid-report`` away.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from hybrid_sysid.report.paper import write_reproduction
from hybrid_sysid.files import write_atomic
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.sweep_figures import transfer_figure
from hybrid_sysid.report.tables import to_markdown

log = logging.getLogger("hybrid_sysid")


class SweepSummary(Callback):
    def __init__(self, reproduction: bool = False, compare: str | None = None, transfer_figure: bool = False):
        self.reproduction = reproduction
        self.compare = compare
        self.transfer_figure = transfer_figure

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        df, table = write_summary(sweep_dir, compare=self.compare)
        print(f"\nmean relative deviation on the test split [%], mean ± std over seeds ({sweep_dir}):\n")
        print(to_markdown(table, compare=self.compare))
        if self.transfer_figure and "scenario" in table.index.names:
            write_atomic(sweep_dir / "figures" / "transfer.png", lambda p: transfer_figure(table, p))
        if self.reproduction:
            print(write_reproduction(sweep_dir))
            print(f"(written to {sweep_dir / 'reproduction.md'})")
        failed = df[df.status != "completed"].drop_duplicates("run")
        if len(failed):
            for _, row in failed.iterrows():
                log.error("job %s %s: %s", row["run"], row["status"], row["error"])
            raise SystemExit(f"{len(failed)} of {df.run.nunique()} jobs failed; summary in {sweep_dir}")
