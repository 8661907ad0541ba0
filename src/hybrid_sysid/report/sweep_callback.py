"""Hydra callback that ends every sweep with its comparison table.

Hydra skips on_multirun_end when a job raised, and with the joblib launcher job callbacks run in worker
processes; so jobs record their own failure and return normally (see hybrid_sysid.cli.train), and the summary here is
built from the run records on disk alone. A sweep with a failed job still exits non-zero.

Options, set under hydra.callbacks.sweep_summary: ``reproduction: true`` (conf/experiment/paper.yaml) also
writes reproduction.md, the paper's figures beside ours; ``compare``: the row key the table's marks compare
(default: objective when swept); ``transfer_figure: true`` (conf/experiment/transfer.yaml) also draws
figures/transfer.png; ``exclude``: glob patterns of run names the table leaves out
(conf/experiment/tuned.yaml: its search trials); ``tuning_table: true`` also writes tuning.md, each search's
result, and figures/tuning.png. Other splits, metrics and the LaTeX table are one
``hybrid-sysid-report`` away.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.report.paper import write_reproduction
from hybrid_sysid.report.summary import threads_warning, write_summary
from hybrid_sysid.report.sweep_figures import transfer_figure, tuning_figure
from hybrid_sysid.report.tables import to_markdown
from hybrid_sysid.report.tuning import tuning_markdown

log = logging.getLogger("hybrid_sysid")


class SweepSummary(Callback):
    def __init__(
        self,
        reproduction: bool = False,
        compare: str | None = None,
        transfer_figure: bool = False,
        exclude=(),
        tuning_table: bool = False,
    ):
        self.reproduction = reproduction
        self.compare = compare
        self.transfer_figure = transfer_figure
        self.exclude = list(exclude)
        self.tuning_table = tuning_table

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        try:
            df, table = write_summary(sweep_dir, compare=self.compare, exclude=self.exclude)
        except Exception as exc:  # Hydra would turn it into a warning and exit 0: the sweep must fail instead
            log.error("sweep summary not written: %s: %s", type(exc).__name__, exc)
            raise SystemExit(f"no summary written in {sweep_dir} ({type(exc).__name__}: {exc})") from exc
        print(f"\nmean relative deviation on the test split [%], mean ± std over seeds ({sweep_dir}):\n")
        print(to_markdown(table, compare=self.compare))
        warning = threads_warning(df)
        if warning:
            log.warning(warning)
        if self.transfer_figure and "scenario" in table.index.names:
            write_atomic(sweep_dir / "figures" / "transfer.png", lambda p: transfer_figure(table, p))
        if self.tuning_table:
            text = tuning_markdown(sweep_dir)
            write_atomic(sweep_dir / "tuning.md", lambda p: p.write_text(text, encoding="utf-8"))
            print(f"\n{text}")
            if "tuning" in table.index.names:
                write_atomic(sweep_dir / "figures" / "tuning.png", lambda p: tuning_figure(table, p))
        if self.reproduction:
            print(write_reproduction(sweep_dir))
            print(f"(written to {sweep_dir / 'reproduction.md'})")
        failed = df[df.status != "completed"].drop_duplicates("run")
        if len(failed):
            for _, row in failed.iterrows():
                log.error("job %s %s: %s", row["run"], row["status"], row["error"])
            raise SystemExit(
                f"{len(failed)} of {df.run.nunique()} jobs failed or were interrupted; summary in {sweep_dir}"
            )
