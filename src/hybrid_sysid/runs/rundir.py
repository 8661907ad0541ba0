"""A run directory, read and written here alone (its file names: runs/layout.py), and its self-describing record,
metrics.json (its fields: docs/run_records.md, "Run records"), never replaced once completed.

Every command reads a run the same way: its record (``record``), its saved config (``saved_config`` as a config,
``saved_values`` as plain data for a report), its group choices and overrides, and the weights it is used with
(``trained_checkpoint``: best, else last). A run directory may come from someone else, so a damaged file is a
one-line ConfigError naming the key that pointed here, never a traceback. The sub-runs that experiments chain
inside one job (experiment=transfer, experiment=tuned) get the same files (``write_config``), so every command
reads them as runs.
"""

from __future__ import annotations

import logging
import os
import shutil
import sys
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config.targets import check_saved
from hybrid_sysid.core.checks import ConfigError, Shown, bad
from hybrid_sysid.core.files import read_json, write_atomic, write_json_atomic, write_yaml_atomic
from hybrid_sysid.core.overrides import Override, parse_overrides
from hybrid_sysid.runs import layout, locks
from hybrid_sysid.runs.reading import load_config, read_yaml
from hybrid_sysid.runs.received import NotData, as_data

log = logging.getLogger("hybrid_sysid")


class CompletedRecordError(RuntimeError):
    """Writing would replace the record of a completed run."""


def run_record(
    status: str,
    overrides: list[str],
    seed: int,
    steps: int = 0,
    train_seconds: float = 0.0,
    results: list[dict] | None = None,
    error: str | None = None,
    **extra,
) -> dict:
    return {
        "status": status,
        "error": error,
        "overrides": list(overrides),
        "seed": seed,
        "steps": steps,
        "train_seconds": round(train_seconds, 2),
        "results": results or [],
        **extra,
    }


def is_completed(record) -> bool:
    return isinstance(record, dict) and record.get("status") == "completed"


class DamagedFile(ConfigError):
    """A file of a run directory that cannot be read; ``why`` says which and how, without the key."""

    @property
    def why(self) -> str:
        text = self.allowed.removeprefix("its ")
        return text.replace(" (", ": ", 1).removesuffix(")") if " (" in text else text


class RunDir:
    """A run directory: where each of its files lies, and what reading or writing them must respect."""

    def __init__(self, path: str | Path):
        self.path = Path(path)

    def __repr__(self) -> str:
        return f"RunDir({str(self.path)!r})"

    def __truediv__(self, name: str) -> Path:
        return self.path / name

    @property
    def config_file(self) -> Path:
        return self.path / layout.CONFIG

    @property
    def checkpoints(self) -> Path:
        return self.path / layout.CHECKPOINTS

    @property
    def record_file(self) -> Path:
        return self.path / layout.RECORD

    def is_run(self) -> bool:
        """Whether the directory holds a record or a saved config (an output may not land inside one)."""
        return self.record_file.is_file() or self.config_file.is_file()

    # -- reading ------------------------------------------------------------------------------------------------

    def record(self, key: str = "run") -> dict | None:
        """The run's record, None when it has none; ConfigError naming ``key`` when it is damaged."""
        if not self.record_file.is_file():
            return None
        try:
            record = read_json(self.record_file)  # a received file: bounded in size, type and depth
        except (OSError, ValueError) as exc:
            self._damaged(key, layout.RECORD, exc)
        if not isinstance(record, dict):
            self._damaged(key, layout.RECORD, "not a mapping")
        return record

    def ended_record(self, key: str = "run") -> dict | None:
        """The record of a run no process writes any more, None when it has none (a run killed, say); ConfigError
        naming ``key`` when another process still holds its writer lock (a run in training: its checkpoints and
        record are not yet what it will leave) or when its record is damaged."""
        if locks.held_elsewhere(self.path):
            why = "another process is still writing it (a run in training, say); use it once that process has ended"
            bad(key, Shown(str(self.path)), f"a run that has ended: {why}")
        return self.record(key)

    def completed_record(self) -> dict | None:
        """The record if it is readable and says completed, else None (missing, truncated, failed...)."""
        try:
            record = self.record()
        except ConfigError:
            return None
        return record if is_completed(record) else None

    def saved_config(self, key: str = "run") -> DictConfig:
        """The composed config the run saved, with this machine's paths (runs.received); ConfigError naming ``key``
        when it has none, is damaged or reads the environment, and naming the class when it builds one neither
        this package's nor an installed plugin's (a plugin not installed here: the package its record names)."""
        if not self.config_file.is_file():
            bad(key, Shown(str(self.path)), f"it has no {layout.CONFIG} (a run directory written by hybrid-sysid)")
        try:
            cfg = load_config(self.config_file)
        except Exception as exc:  # noqa: BLE001 - yaml's errors are many classes; the message says which
            self._damaged(key, layout.CONFIG, exc)
        if not isinstance(cfg, DictConfig):
            self._damaged(key, layout.CONFIG, "not a mapping")
        try:  # this machine's paths; no interpolation that reads the environment or files (runs.received)
            as_data(cfg)
        except NotData as exc:
            self._damaged(key, layout.CONFIG, str(exc), "is read as data only")
        try:
            record = self.record(key)
        except ConfigError:  # damaged: the refusal of a missing plugin then names no package
            record = None
        check_saved(cfg, record)
        return cfg

    def saved_values(self) -> dict:
        """The saved config as plain data (interpolations unresolved), {} when absent or damaged: what a report
        reads of a run it tabulates."""
        values = read_yaml(self.config_file)
        return values if isinstance(values, dict) else {}

    def choices(self) -> dict:
        """The run's config-group choices (objective, model, data, ...), {} when unknown."""
        hydra = read_yaml(self.path / layout.HYDRA)
        choices = (
            ((hydra or {}).get("hydra") or {}).get("runtime", {}).get("choices") if isinstance(hydra, dict) else None
        )
        return choices if isinstance(choices, dict) else {}

    def config_name(self) -> str | None:
        """The primary config the run was composed from (config: hybrid-sysid, eval: hybrid-sysid-eval)."""
        hydra = read_yaml(self.path / layout.HYDRA)
        job = ((hydra or {}).get("hydra") or {}).get("job") if isinstance(hydra, dict) else None
        return job.get("config_name") if isinstance(job, dict) else None

    def overrides(self) -> list[str]:
        """The command-line overrides Hydra saved before the job started ([] when unknown): a job whose record is
        damaged still has a known configuration."""
        saved = read_yaml(self.path / layout.OVERRIDES)
        return [str(o) for o in saved] if isinstance(saved, list) else []

    def parsed_overrides(self) -> list[Override]:
        """``overrides``, each parsed as (prefix, key, value) (core.overrides.parse_override)."""
        return parse_overrides(self.overrides())

    def trained_checkpoint(self, key: str = "run", which: str | None = None) -> Path:
        """The weights a trained run is used with: best.ckpt, or last.ckpt when it never validated (``which``:
        "best" or "last" for that one alone); ConfigError naming ``key`` otherwise."""
        names = layout.TRAINED if which is None else (f"{which}.ckpt",)
        if which is not None and names[0] not in layout.TRAINED:
            bad("checkpoint", which, "best or last (None: best, else last)")
        for name in names:
            path = self.checkpoints / name
            if path.is_file():
                return path
            if path.exists() or path.is_symlink():  # a FIFO, device or folder: never fall back to other weights
                bad(key, Shown(str(self.path)), f"a run whose checkpoints/{name} is a regular file (it is not)")
        trained = f"a run that trained a network, with checkpoints/{' or '.join(names)} (hybrid-sysid writes both)"
        bad(key, Shown(str(self.path)), trained)

    def load_weights(self, key: str = "run", which: str | None = None) -> tuple[Path, dict]:
        """The trained checkpoint (``trained_checkpoint``) and its state_dict; ConfigError naming ``key`` when it
        cannot be read (truncated, another format)."""
        import torch  # deferred

        path = self.trained_checkpoint(key, which)
        try:
            return path, torch.load(path, map_location="cpu", weights_only=True)["state_dict"]
        except Exception as exc:  # noqa: BLE001 - torch raises several classes for a damaged or foreign file
            self._damaged(key, str(path.relative_to(self.path)), exc, "cannot be read")

    def read_table(self, name: str):
        """predictions.csv or curves.csv as a DataFrame; OSError or ValueError when absent or damaged."""
        import pandas as pd  # deferred

        return pd.read_csv(self.path / name)

    # -- writing ------------------------------------------------------------------------------------------------

    def write_config(self, cfg: DictConfig, overrides: list[str]) -> None:
        """config.yaml and overrides.yaml, as Hydra writes them for a job before it starts; never over a completed
        run's, which belong to its record (a re-run skips that run, or refuses other overrides)."""
        if self.completed_record() is None:
            write_yaml_atomic(self.config_file, OmegaConf.to_container(cfg))
            write_yaml_atomic(self.path / layout.OVERRIDES, list(overrides))

    def write_tables(self, predictions, curves) -> None:
        """predictions.csv and curves.csv (DataFrames); the run's figures are drawn from them."""
        for name, table in ((layout.CURVES, curves), (layout.PREDICTIONS, predictions)):
            write_atomic(self.path / name, lambda p, table=table: table.to_csv(p, index=False))

    def write_record(self, record: dict) -> None:
        """metrics.json, atomically; never over a completed run's record (a run is final once done)."""
        if self.completed_record() is not None:
            raise CompletedRecordError(f"{self.record_file} holds a completed run; not replacing it")
        write_json_atomic(self.record_file, record)

    def previous_record(self, overrides) -> dict | None:
        """The record of a run of these overrides that already completed here (a re-run skips it), else None. A
        record that cannot be read (e.g. truncated) is no completed run: the job runs again. A completed run of
        other overrides is a ConfigError."""
        try:
            record = self.record()
        except ConfigError as exc:
            log.warning("%s; running the job again", exc)
            return None
        if not is_completed(record):
            return None
        wanted = [o for o in overrides if not o.startswith("resume=")]
        had = [o for o in record.get("overrides", []) if not o.startswith("resume=")]
        if sorted(had) != sorted(wanted):
            other = f"it holds a completed run of other overrides ({' '.join(had)})"
            bad("hydra.run.dir", Shown(str(self.path)), f"{other}; choose another hydra.run.dir / hydra.sweep.dir")
        return record

    def drop_stale_record(self) -> None:
        """Remove the record of a job that failed or was interrupted before, once the job has completed all its
        work in sub-directories (experiment=transfer, experiment=tuned: their runs hold the records), so the sweep
        summary no longer counts it as failed. A completed record is never removed."""
        if self.record_file.is_file() and self.completed_record() is None:
            log.info("%s: the earlier record superseded by the completed runs below it", self.record_file)
            self.record_file.unlink()

    def record_end(self, overrides, seed, status: str, error: str) -> dict:
        """Record a failed or interrupted job, unless the directory holds a completed run (never replaced). A
        record that cannot be written (a full disk) is reported on one line instead."""
        if (problem := self.try_record_end(overrides, seed, status, error)) is not None:
            print(f"error: could not record the {status} job in {self.path}: {problem}", file=sys.stderr)
        return {"status": status, "error": error}

    def try_record_end(self, overrides, seed, status: str, error: str) -> str | None:
        """``record_end`` without its line: what kept the record from being written (a full disk), else None."""
        if self.completed_record() is None:
            try:
                self.path.mkdir(parents=True, exist_ok=True)
                self.write_record(run_record(status, overrides, seed, error=error))
            except (OSError, CompletedRecordError) as exc:
                return f"{type(exc).__name__}: {exc}"
        return None

    def discard(self) -> bool:
        """Remove the directory and everything in it, unless it holds a completed record (a run is final once
        done); whether it is gone. For a directory this process made for a job that left nothing of use: an
        evaluation onto a full disk, whose half-written files no command could read as a run."""
        if self.completed_record() is not None:
            return False
        # the job's log file lies inside: closed first, so no later message is written into a removed file
        here = os.path.abspath(self.path)
        for handler in logging.getLogger().handlers[:]:
            if isinstance(handler, logging.FileHandler) and os.path.dirname(handler.baseFilename) == here:
                logging.getLogger().removeHandler(handler)
                handler.close()
        shutil.rmtree(self.path, ignore_errors=True)
        return not self.path.exists()

    def _damaged(self, key: str, name: str, why, verb: str = "is damaged") -> None:
        if isinstance(why, BaseException):
            why = f"{type(why).__name__}: {' '.join(str(why).split())[:200]}"
        raise DamagedFile(key, Shown(str(self.path)), f"its {name} {verb} ({why})")
