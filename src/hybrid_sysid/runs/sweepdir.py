"""A sweep directory: Hydra's record of the sweep (multirun.yaml) read as a config or as plain data, whether a
command may run into it again (``check_rerun``), and the state its processes share while it runs: the stop mark
(runs.layout.STOP_MARKER) and the progress file (runs.layout.PROGRESS)."""

from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import flatten
from hybrid_sysid.config.versions import upgraded
from hybrid_sysid.core.checks import Shown, bad
from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.runs import layout
from hybrid_sysid.runs.reading import load_config, read_yaml

KEY = "hydra.sweep.dir"
ABSENT = "(absent)"


class SweepDir:
    def __init__(self, path: str | Path):
        self.path = Path(path)

    @property
    def config_file(self) -> Path:
        return self.path / layout.SWEEP_CONFIG

    def saved_config(self) -> DictConfig | None:
        """multirun.yaml as a config; None when it is absent or cannot be read."""
        try:
            cfg = load_config(self.config_file)
        except Exception:  # noqa: BLE001 - absent or damaged: the caller decides what that means
            return None
        return cfg if isinstance(cfg, DictConfig) else None

    def saved_values(self) -> dict:
        """multirun.yaml as plain data (interpolations unresolved), {} when absent or damaged."""
        values = read_yaml(self.config_file)
        return values if isinstance(values, dict) else {}

    def write_config(self, cfg: DictConfig) -> None:
        write_atomic(self.config_file, lambda p: OmegaConf.save(cfg, p))

    def holds_runs(self) -> bool:
        """Whether a job of an earlier sweep wrote here: a record or a saved config at any depth (a run of
        experiment=tuned sits two levels below its job)."""
        return any(self.path.rglob(layout.RECORD)) or any(self.path.rglob(".hydra"))

    # the sweep's state beside its runs, shared by its processes: the stop mark and the progress file
    @property
    def stop_marker(self) -> Path:
        return self.path / layout.STOP_MARKER

    def stopped(self) -> bool:
        """Whether one of the sweep's processes took a signal: its jobs not yet started skip."""
        return self.stop_marker.exists()

    def mark_stopped(self) -> None:
        """Mark the sweep interrupted, so jobs not yet started skip; a directory not yet made gets no mark."""
        if self.path.is_dir():
            self.stop_marker.touch()

    def clear_stopped(self) -> None:
        """A re-run continues an interrupted sweep."""
        self.stop_marker.unlink(missing_ok=True)

    @property
    def progress_file(self) -> Path:
        return self.path / layout.PROGRESS

    def start_progress(self, header: dict) -> None:
        """The progress file anew with its header line (launch.progress); OSError if it cannot be written."""
        self.path.mkdir(parents=True, exist_ok=True)
        self.progress_file.write_text(json.dumps(header) + "\n", encoding="utf-8")

    def add_progress(self, entry: dict) -> list[str]:
        """Append one JSON line to the progress file and return all its lines, under one lock (parallel workers
        write in turn). A missing file (a sweep started elsewhere) stays missing: its first line would not be a
        header, so FileNotFoundError."""
        with open(self.progress_file, "r+", encoding="utf-8") as f:
            fcntl.flock(f, fcntl.LOCK_EX)
            try:
                f.seek(0, os.SEEK_END)
                f.write(json.dumps(entry) + "\n")
                f.flush()
                f.seek(0)
                return f.read().splitlines()
            finally:
                fcntl.flock(f, fcntl.LOCK_UN)

    def progress_with(self, entry: dict) -> tuple[dict, list[dict]]:
        """``add_progress``, then the file read back: its header and its events (a bare number, as an older file
        has it, is the end of that job). ValueError when the first line is not a header."""
        lines = self.add_progress(entry)
        header = json.loads(lines[0])
        if not isinstance(header, dict):
            raise ValueError(f"{self.progress_file} has no header")
        events = [e if isinstance(e, dict) else {"end": e} for e in map(json.loads, lines[1:])]
        return header, events

    def check_rerun(self, config: DictConfig) -> None:
        """A sweep run again into this directory must be the sweep that made it: the same command-line overrides,
        the same sweeper parameters and the same composed config (a file of the user's --config-dir may have
        changed). Without a readable multirun.yaml, a directory holding runs cannot be told to be the same sweep,
        whatever the command: each job's directory would get another sweep's .hydra/. ConfigError otherwise."""
        if not self.path.is_dir():
            return
        saved = self.saved_values()
        hydra = saved.get("hydra")
        if not isinstance(hydra, dict) or not isinstance((hydra.get("overrides") or {}).get("task"), list):
            if self.holds_runs():
                bad(
                    KEY,
                    Shown(str(self.path)),
                    f"it holds runs but its {layout.SWEEP_CONFIG} is missing or damaged, so this command cannot be "
                    f"told to be the sweep that made them; choose another {KEY}",
                )
            return
        was = _sweep_of(saved)
        now = _sweep_of(OmegaConf.to_container(config, resolve=False))
        if was != now:
            bad(
                KEY,
                Shown(str(self.path)),
                f"it holds a sweep of other overrides ({' '.join(was[0])}); re-run it with the same ones, or choose "
                f"another {KEY}",
            )
        change = first_difference(_task(saved), _task(OmegaConf.to_container(config, resolve=False)))
        if change is not None:
            key, there, here = change
            bad(
                KEY,
                Shown(str(self.path)),
                f"it holds a sweep made with another config ({key}: {there} there, {here} here: a config file "
                f"changed, or its {layout.SWEEP_CONFIG} is damaged); choose another {KEY}",
            )


def _sweep_of(values: dict) -> tuple:
    """What makes a sweep's jobs: its command-line overrides and the sweeper's parameters (an experiment's)."""
    hydra = values.get("hydra") or {}
    params = (hydra.get("sweeper") or {}).get("params")
    return sorted(str(o) for o in hydra["overrides"]["task"]), params or {}


def _task(values: dict) -> dict:
    """The config the jobs are composed from, without Hydra's section."""
    return {k: v for k, v in values.items() if k != "hydra"}


def first_difference(there: dict, here: dict):
    """The first dotted key whose value differs between two plain configs, as (key, there, here); None when equal.
    A key added since a config was saved (config.versions) reads as its default there: a sweep or run made
    before ``tags`` existed is the same config as one with ``tags: []``."""
    was, now = (upgraded(flatten(c)) for c in (there, here))
    key = next((k for k in sorted(was.keys() | now.keys()) if was.get(k, ABSENT) != now.get(k, ABSENT)), None)
    return None if key is None else (key, was.get(key, ABSENT), now.get(key, ABSENT))


def sweep_dir_of(run_dir: Path) -> Path | None:
    """The nearest directory at or above run_dir holding a multirun.yaml (a run of experiment=tuned sits two
    levels below its job), None for a run outside a sweep."""
    for d in (Path(run_dir), *Path(run_dir).parents):
        if (d / layout.SWEEP_CONFIG).is_file():
            return d
    return None
