"""Every file name of a run or sweep directory, spelled here alone (the readers and writers are RunDir and
SweepDir beside it)::

    <run>/.hydra/config.yaml      the composed config the run was made with (Hydra writes it before the job)
    <run>/.hydra/overrides.yaml   its command-line overrides
    <run>/.hydra/hydra.yaml       Hydra's own settings (the group choices)
    <run>/checkpoints/best.ckpt   the weights model selection chose; last.ckpt: the newest training state
    <run>/metrics.json            the record (runs.rundir), written last
    <run>/predictions.csv         one row per recording and evaluation; curves.csv: the learning curves
    <run>/figures/                the run's figures (report.run_figures)
    <sweep>/multirun.yaml         Hydra's record of the sweep's command line
"""

from pathlib import Path

from hybrid_sysid.core.checks import ConfigError, Shown

CONFIG, OVERRIDES, HYDRA = ".hydra/config.yaml", ".hydra/overrides.yaml", ".hydra/hydra.yaml"
RECORD = "metrics.json"
PREDICTIONS, CURVES = "predictions.csv", "curves.csv"
FIGURES = "figures"
CHECKPOINTS = "checkpoints"
BEST, LAST = "best.ckpt", "last.ckpt"
TRAINED = (BEST, LAST)  # the weights a trained run is used with: best, else last
WRITER_LOCK = ".writer.lock"  # in a run or sweep directory: held by the one process that writes there
SWEEP_CONFIG = "multirun.yaml"
OUTSIDE_RUNS = "a path outside run and sweep directories, whose files are their record"
STOP_MARKER = ".interrupted"  # in a sweep directory: the sweep was interrupted, jobs not yet started skip
PROGRESS = ".progress"  # in a sweep directory: a JSON header (jobs, kinds, start), a JSON line per job start, end
# what a run's MLflow run keeps of its files: the file -> its folder among the artifacts
TRACKED = {RECORD: "", CURVES: "", CONFIG: "config", OVERRIDES: "config", HYDRA: "config"}


def enclosing_run(path):
    """The run or sweep directory at or above ``path`` (links and ``..`` resolved): the nearest folder holding
    .hydra/, multirun.yaml or metrics.json; None outside any. An output never lands there: those files are a
    record only their own command writes."""
    path = Path(path).resolve()
    for folder in (path, *path.parents):
        if (folder / ".hydra").is_dir() or (folder / SWEEP_CONFIG).is_file() or (folder / RECORD).is_file():
            return folder
    return None


def check_outside_runs(key: str, path, under=None, error: type = ConfigError) -> None:
    """An output ``path`` lies in no run or sweep directory (``enclosing_run`` of ``under``, by default of ``path``
    itself): else ``error`` naming ``key``. The one refusal of train's and eval's directories, predict's output=
    and the report's results= and out=."""
    holder = enclosing_run(path if under is None else under)
    if holder is not None:
        raise error(key, Shown(str(path)), f"it lies inside the run or sweep directory {holder}; {OUTSIDE_RUNS}")
