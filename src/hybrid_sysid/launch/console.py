"""What a command prints on the console; the run's log file (``<run dir>/train.log``, Hydra's job logging,
conf/hydra/job_logging/quiet.yaml) keeps every message.

- Lightning's messages go through Hydra's logging once: Lightning adds a console handler of its own to its
  loggers when imported, so with Hydra's handlers on the root logger every message printed twice
  (``quiet_libraries``). Its INFO messages (seed, devices, why fit stopped) go to the log file only, and its
  litlogger advert nowhere.
- In a sweep, what a job logs below WARNING goes to its log file only (its result table among it): the console
  shows one line per finished job (hybrid_sysid.launch.sweep) and the sweep's table; a single run
  also prints its own messages and table.
"""

from __future__ import annotations

import logging
import os
import sys
import warnings
from contextlib import contextmanager

from hybrid_sysid.launch.state import PROCESS

LIGHTNING = ("lightning", "lightning.pytorch", "lightning.fabric")
# what a job in a sweep still shows below WARNING (logger, words in the message): the (long) simulation of a
# dataset not yet cached, and a re-run sweep's job that is not run again
SWEEP_INFO = (("hybrid_sysid.data.cache", "simulating"), ("hybrid_sysid", "already completed"))
SRUN_ADVERT = "The `srun` command is available on your system but is not used"  # lightning.fabric's SLURMEnvironment


def tolerant_streams() -> None:
    """stdout and stderr write what their encoding cannot as backslash escapes: under an ASCII locale (LC_ALL=C) a
    path outside ASCII, or the table's Cramér-Rao row, raised UnicodeEncodeError in the middle of a run's logging."""
    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")


class ConsoleFilter(logging.Filter):
    """The filter of the console handler of Hydra's job logging. ``mode``: hydra.mode (RUN or MULTIRUN)."""

    def __init__(self, mode=None):
        super().__init__()
        self.sweep = str(mode).endswith("MULTIRUN")

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.WARNING:
            return True
        name = record.name
        if name == "lightning" or name.startswith(("lightning.", "pytorch_lightning", "lightning_fabric")):
            return False  # the run's log file has them
        if self.sweep and PROCESS.job_running and name.startswith("hybrid_sysid"):
            return any(name == logger and words in str(record.msg) for logger, words in SWEEP_INFO)
        return True


class _NoAdverts(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return "litlogger" not in str(record.msg)


@contextmanager
def job_running():
    """Within: the job's own work (its INFO messages stay off a sweep's console)."""
    PROCESS.job_running = True
    try:
        yield
    finally:
        PROCESS.job_running = False


def quiet_libraries() -> None:
    """Lightning's messages through the root logger's handlers alone (Hydra's console and the run's log file),
    without its advert for litlogger (logged at every Trainer's creation), and without a deprecation warning of
    torch about Lightning's own code, which no user can act on. Lightning is imported here (the job's work
    imports it next anyway) because its import adds the console handlers removed here. Outside a SLURM job,
    Lightning's hint that srun is on PATH but not used (a cluster's login node) is dropped: it speaks of SLURM jobs
    and this process is none. Without handlers on the root logger (plain Python, not a command), nothing else
    changes."""
    if "SLURM_JOB_ID" not in os.environ:
        warnings.filterwarnings("ignore", message=SRUN_ADVERT)
    if not logging.getLogger().handlers:
        return
    import lightning  # noqa: F401 - deferred

    for name in LIGHTNING:
        logger = logging.getLogger(name)
        for handler in list(logger.handlers):
            if type(handler) is logging.StreamHandler:  # Lightning's own console handler, not a file
                logger.removeHandler(handler)
        logger.propagate = True
    rank_zero = logging.getLogger("lightning.pytorch.utilities.rank_zero")
    if not any(isinstance(f, _NoAdverts) for f in rank_zero.filters):
        rank_zero.addFilter(_NoAdverts())
    warnings.filterwarnings("ignore", message=r"`isinstance\(treespec, LeafSpec\)`", category=FutureWarning)
