"""One run directory's layout, known here alone: Hydra's saved config, the checkpoints, the record.

::

    <run>/.hydra/config.yaml      the composed config the run was made with (Hydra writes it before the job)
    <run>/.hydra/overrides.yaml   its command-line overrides
    <run>/.hydra/hydra.yaml       Hydra's own settings (the group choices)
    <run>/checkpoints/best.ckpt   the weights model selection chose; last.ckpt: the newest training state
    <run>/metrics.json            the record (hybrid_sysid.runs.records), written last

The sub-runs that experiments chain inside one job (experiment=transfer, experiment=tuned) get the same files
(``write_config``), so every command reads them as runs.
"""

from __future__ import annotations

import json
import logging
import sys
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import flatten
from hybrid_sysid.core.checks import ConfigError, bad
from hybrid_sysid.core.files import write_yaml_atomic
from hybrid_sysid.runs.records import (
    RECORD,
    CompletedRecordError,
    completed_record,
    previous_record,
    run_record,
    write_record,
)

log = logging.getLogger("hybrid_sysid")
CONFIG, OVERRIDES, HYDRA = ".hydra/config.yaml", ".hydra/overrides.yaml", ".hydra/hydra.yaml"
CHECKPOINTS = ("best.ckpt", "last.ckpt")  # the weights a trained run is used with: best, else last
WRITER_LOCK = ".writer.lock"  # in a run or sweep directory: held by the one process that writes there
# keys that cannot change a run's numbers: a resumed run may differ in them (a name ending in "." frees every key
# under it: where a run's files go, conf/paths)
# keys that cannot change a run's weights or scores: which noise levels the learning curves are taken at changes
# only which curve rows are recorded (an interrupted sweep made before noise.curve_std existed still continues)
RESUME_FREE = {"resume", "data.cache_dir", "trainer.progress_bar", "trainer.profiler", "paths.", "noise.curve_std"}
# keys added to the configs after runs were made, with the value that gives a run without them its own numbers:
# a saved config lacking one of them agrees with that value
ADDED = {"objective.target": "residual"}


class RunDir:
    """A run directory: where each of its files lies, and what reading or writing them must respect."""

    def __init__(self, path: str | Path):
        self.path = Path(path)

    def __repr__(self) -> str:
        return f"RunDir({str(self.path)!r})"

    @property
    def config_file(self) -> Path:
        return self.path / CONFIG

    @property
    def overrides_file(self) -> Path:
        return self.path / OVERRIDES

    @property
    def hydra_file(self) -> Path:
        return self.path / HYDRA

    @property
    def checkpoints(self) -> Path:
        return self.path / "checkpoints"

    @property
    def record_file(self) -> Path:
        return self.path / RECORD

    def saved_config(self, key: str) -> DictConfig:
        """The composed config the run saved; ConfigError naming ``key`` when it has none or it is damaged."""
        if not self.config_file.is_file():
            raise ConfigError(
                f"{key} = {str(self.path)!r} is not allowed: it has no {CONFIG} (a run directory "
                "written by hybrid-sysid)"
            )
        try:
            cfg = OmegaConf.load(self.config_file)
        except Exception as exc:  # noqa: BLE001 - yaml's errors are many classes; the message says which
            raise ConfigError(
                f"{key} = {str(self.path)!r} is not allowed: its {CONFIG} is damaged "
                f"({type(exc).__name__}: {' '.join(str(exc).split())})"
            ) from None
        if not isinstance(cfg, DictConfig):
            raise ConfigError(f"{key} = {str(self.path)!r} is not allowed: its {CONFIG} is damaged (not a mapping)")
        return cfg

    def read_record(self, key: str) -> dict | None:
        """The run's record, None when it has none; ConfigError naming ``key`` when it is damaged."""
        if not self.record_file.is_file():
            return None
        try:
            record = json.loads(self.record_file.read_text())
        except (OSError, ValueError) as exc:
            raise ConfigError(
                f"{key} = {str(self.path)!r} is not allowed: its {RECORD} is damaged ({type(exc).__name__}: {exc})"
            ) from None
        if not isinstance(record, dict):
            raise ConfigError(f"{key} = {str(self.path)!r} is not allowed: its {RECORD} is damaged (not a mapping)")
        return record

    def load_weights(self, key: str) -> tuple[Path, dict]:
        """The trained checkpoint (``trained_checkpoint``) and its state_dict; ConfigError naming ``key`` when it
        cannot be read (truncated, another format)."""
        import torch  # here: reading a run's layout loads no torch

        path = self.trained_checkpoint(key)
        try:
            return path, torch.load(path, map_location="cpu", weights_only=True)["state_dict"]
        except Exception as exc:  # noqa: BLE001 - torch raises several classes for a damaged or foreign file
            raise ConfigError(
                f"{key} = {str(self.path)!r} is not allowed: its {path.relative_to(self.path)} cannot be read "
                f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
            ) from None

    def write_config(self, cfg: DictConfig, overrides: list[str]) -> None:
        """config.yaml and overrides.yaml, as Hydra writes them for a job before it starts."""
        write_yaml_atomic(self.config_file, OmegaConf.to_container(cfg))
        write_yaml_atomic(self.overrides_file, list(overrides))

    def trained_checkpoint(self, key: str) -> Path:
        """The weights a trained run is used with: best.ckpt, or last.ckpt when it never validated; ConfigError
        naming ``key`` otherwise."""
        for name in CHECKPOINTS:
            if (self.checkpoints / name).is_file():
                return self.checkpoints / name
        raise ConfigError(
            f"{key} = {str(self.path)!r} is not allowed: it holds no checkpoints/"
            f"{' or '.join(CHECKPOINTS)} (a run directory of hybrid-sysid that trained a network)"
        )

    def resume_checkpoint(self) -> Path | None:
        """The checkpoint to resume from: last.ckpt; best.ckpt when last.ckpt is damaged (both hold the full
        training state); None (train from the beginning, which gives the same numbers) when best.ckpt is damaged,
        as the best weights the run would be evaluated with are then lost, or when neither loads. Damaged files are
        reported and overwritten by the run's next checkpoints, so a damaged file never blocks a run."""
        ok = {}
        for name in ("last.ckpt", "best.ckpt"):
            path = self.checkpoints / name
            if path.exists():
                ok[name] = _loadable(path)
                if not ok[name]:
                    log.warning("checkpoint %s cannot be loaded (damaged or truncated); not resuming from it", path)
        if ok.get("best.ckpt", True) is False or (ok and not any(ok.values())):
            log.warning("training %s from the beginning", self.path)
            return None
        if ok.get("last.ckpt"):
            return self.checkpoints / "last.ckpt"
        return self.checkpoints / "best.ckpt" if ok.get("best.ckpt") else None

    def check_resume(self, cfg: DictConfig, overrides=()) -> None:
        """``resume=`` must name a run (its saved config, written before any of its work) of this config: every
        value but those that cannot change the numbers (RESUME_FREE) the same. ConfigError naming the keys. A saved
        config that parses but lacks keys (a truncated file) is reported as damaged, with the command that
        rewrites it from ``overrides`` (this command's) when the keys it holds agree."""
        if not self.path.is_dir():
            bad("resume", str(self.path), "no such directory; give the directory of the run to continue")
        if not self.config_file.is_file():
            bad("resume", str(self.path), f"the directory holds no run (no {CONFIG})")
        try:
            saved = OmegaConf.to_container(OmegaConf.load(self.config_file), resolve=False)
        except Exception as exc:  # noqa: BLE001 - a damaged file cannot tell; the run's own files still resume
            log.warning("%s is unreadable (%s); resuming without comparing the configs", self.config_file, exc)
            return
        now = flatten(OmegaConf.to_container(cfg, resolve=False))
        was = flatten(saved if isinstance(saved, dict) else {})
        differ = [k for k in sorted(set(now) | set(was)) if not _resume_free(k) and _value(now, k) != _value(was, k)]
        held = [k for k in differ if k in was]
        if differ and not held:  # every difference is a key the file lacks: a damaged file, not another run
            lacking = [k for k in differ if k in now]
            command = " ".join(["hybrid-sysid", *overrides, "--cfg", "job"])
            bad(
                "resume",
                str(self.path),
                f"its {CONFIG} is damaged: it lacks {len(lacking)} keys ({', '.join(lacking[:3])}"
                f"{', ...' if len(lacking) > 3 else ''}) and the {len(was)} it holds agree with this config; "
                f"rewrite it with `{command} > {self.config_file}` and resume again",
            )
        if differ:
            first = held + [k for k in differ if k not in held]  # values it holds first, then keys it lacks
            shown = "; ".join(f"{k} = {_value(was, k)!r} there, {_value(now, k)!r} here" for k in first[:3])
            bad(
                "resume",
                str(self.path),
                f"it holds a run of another config ({shown}"
                f"{'; ...' if len(differ) > 3 else ''}); resume with the run's own values",
            )

    def completed_record(self) -> dict | None:
        return completed_record(self.path)

    def previous_record(self, overrides) -> dict | None:
        """The record of a run of these overrides that already completed here (a re-run skips it), else None;
        ValueError for a completed run of other overrides."""
        return previous_record(self.path, overrides)

    def write_record(self, record: dict) -> None:
        write_record(self.path, record)

    def drop_stale_record(self) -> None:
        """Remove the record of a job that failed or was interrupted before, once the job has completed all its
        work in sub-directories (experiment=transfer, experiment=tuned: their runs hold the records), so the sweep
        summary no longer counts it as failed. A completed record is never removed."""
        if self.record_file.is_file() and self.completed_record() is None:
            log.info("%s: the earlier %s superseded by the completed runs below it", self.record_file, "record")
            self.record_file.unlink()

    def record_end(self, overrides, seed, status: str, error: str) -> dict:
        """Record a failed or interrupted job, unless the directory holds a completed run (never replaced). A
        record that cannot be written (a full disk) is reported on one line instead."""
        if self.completed_record() is None:
            try:
                self.path.mkdir(parents=True, exist_ok=True)
                self.write_record(run_record(status, overrides, seed, error=error))
            except (OSError, CompletedRecordError) as exc:
                print(
                    f"error: could not record the {status} job in {self.path}: {type(exc).__name__}: {exc}",
                    file=sys.stderr,
                )
        return {"status": status, "error": error}


def hold_for_writing(path: Path, key: str):
    """Take the one-writer lock of a run or sweep directory (an advisory flock on WRITER_LOCK inside it, released
    when the holder releases it or ends, however it ends) and return it; ConfigError naming ``key`` when another
    process holds it. The directory must exist."""
    from filelock import FileLock, Timeout

    lock = FileLock(str(Path(path) / WRITER_LOCK), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise ConfigError(
            f"{key} = {path} is not allowed: another process is writing there (a run or sweep of hybrid-sysid); "
            f"wait until it ends, or choose another {key}"
        ) from None
    return lock


def _loadable(path: Path) -> bool:
    import torch  # here: a sweep's parent process reads run directories without loading torch

    try:
        torch.load(path, map_location="cpu", weights_only=True)
        return True
    except Exception:  # noqa: BLE001 - truncated, garbage, another format: all mean "cannot resume from it"
        return False


def _resume_free(key: str) -> bool:
    return key in RESUME_FREE or any(key.startswith(p) for p in RESUME_FREE if p.endswith("."))


def _value(flat: dict, key: str):
    """A flattened config's value at ``key``; an empty mapping, or a key of ADDED at its value there, counts as unset
    (a run saved before a group such as callbacks existed lacks the key that now holds {})."""
    value = flat.get(key, "(unset)")
    return "(unset)" if value == {} or (key in ADDED and value == ADDED[key]) else value
