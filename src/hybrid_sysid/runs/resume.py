"""Resuming a run (``resume=DIR``): what it must be of the same config, and which checkpoint it continues from."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import flatten
from hybrid_sysid.config.versions import upgraded
from hybrid_sysid.core.checks import Shown, bad
from hybrid_sysid.runs import layout
from hybrid_sysid.runs.reading import load_config
from hybrid_sysid.runs.rundir import RunDir

log = logging.getLogger("hybrid_sysid")
_uncompared: list[str] = []  # warn_uncompared's messages, from the preflight to the job's log file
# keys that cannot change a run's weights or scores, so a resumed run may differ in them (a name ending in "."
# frees every key under it: where a run's files go, conf/paths); which noise levels the learning curves are taken
# at changes only which curve rows are recorded; tags only label the run
RESUME_FREE = {
    "resume",
    "data.cache_dir",
    "trainer.progress_bar",
    "trainer.profiler",
    "paths.",
    "noise.curve_std",
    "tags",
}


def check_resume(run: RunDir, cfg: DictConfig, overrides=()) -> None:
    """``resume=`` must name a run (its saved config, written before any of its work) of this config: every
    value but those that cannot change the numbers (RESUME_FREE) the same. ConfigError naming the keys. A saved
    config that parses but lacks keys (a truncated file) is reported as damaged, with the command that rewrites it
    from ``overrides`` (this command's) when the keys it holds agree."""
    if not run.path.is_dir():
        bad("resume", Shown(str(run.path)), "no such directory; give the directory of the run to continue")
    if not run.config_file.is_file():
        bad("resume", Shown(str(run.path)), f"the directory holds no run (no {layout.CONFIG})")
    try:
        saved = OmegaConf.to_container(load_config(run.config_file), resolve=False)
    except Exception as exc:  # noqa: BLE001 - a damaged file cannot tell; the run's own files still resume
        why = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
        warn_uncompared(f"{run.config_file} cannot be read ({why}); resuming without comparing the configs")
        return
    now = upgraded(flatten(OmegaConf.to_container(cfg, resolve=False)))
    file = flatten(saved if isinstance(saved, dict) else {})
    was = upgraded(file)  # a key added since it was saved: the run did what its default does
    differ = [k for k in sorted(set(now) | set(was)) if not _resume_free(k) and _value(now, k) != _value(was, k)]
    held = [k for k in differ if k in was]
    if differ and not held:  # every difference is a key the file lacks: a damaged file, not another run
        lacking = [k for k in differ if k in now]
        command = " ".join(["hybrid-sysid", *overrides, "--cfg", "job"])
        bad(
            "resume",
            Shown(str(run.path)),
            f"its {layout.CONFIG} is damaged: it lacks {len(lacking)} keys ({', '.join(lacking[:3])}"
            f"{', ...' if len(lacking) > 3 else ''}) and the {len(file)} it holds agree with this config; "
            f"rewrite it with `{command} > {run.config_file}` and resume again",
        )
    if differ:
        first = held + [k for k in differ if k not in held]  # values it holds first, then keys it lacks
        shown = "; ".join(f"{k} = {_value(was, k)!r} there, {_value(now, k)!r} here" for k in first[:3])
        bad(
            "resume",
            Shown(str(run.path)),
            f"it holds a run of another config ({shown}{'; ...' if len(differ) > 3 else ''}); resume with the run's "
            "own values",
        )


def warn_uncompared(message: str) -> None:
    """A resume that goes on unchecked: one line on stderr now (the preflight runs before Hydra opens the job's
    log file, and its logging would print it among Hydra's own lines on stdout), kept for the run's log file,
    where the job writes it (``uncompared``)."""
    print(f"warning: {message}", file=sys.stderr, flush=True)
    _uncompared.append(message)


def uncompared() -> list[str]:
    """The warnings of ``warn_uncompared`` not yet taken, now taken: the job writes them to its log file."""
    taken = list(_uncompared)
    _uncompared.clear()
    return taken


def resume_checkpoint(run: RunDir) -> Path | None:
    """The checkpoint to resume from: last.ckpt; best.ckpt when last.ckpt is damaged (both hold the full training
    state); None (train from the beginning, which gives the same numbers) when best.ckpt is damaged, as the best
    weights the run would be evaluated with are then lost, or when neither loads. Damaged files are reported and
    overwritten by the run's next checkpoints, so a damaged file never blocks a run."""
    ok = {}
    for name in (layout.LAST, layout.BEST):
        path = run.checkpoints / name
        if path.exists():
            ok[name] = _loadable(path)
            if not ok[name]:
                log.warning("checkpoint %s cannot be loaded (damaged or truncated); not resuming from it", path)
    if ok.get(layout.BEST, True) is False or (ok and not any(ok.values())):
        log.warning("training %s from the beginning", run.path)
        return None
    if ok.get(layout.LAST):
        return run.checkpoints / layout.LAST
    return run.checkpoints / layout.BEST if ok.get(layout.BEST) else None


def _loadable(path: Path) -> bool:
    import torch  # deferred

    try:
        torch.load(path, map_location="cpu", weights_only=True)
        return True
    except Exception:  # noqa: BLE001 - truncated, garbage, another format: all mean "cannot resume from it"
        return False


def _resume_free(key: str) -> bool:
    return key in RESUME_FREE or any(key.startswith(p) for p in RESUME_FREE if p.endswith("."))


def _value(flat: dict, key: str):
    """A flattened config's value at ``key``; an empty mapping counts as unset (a run saved before a group such as
    callbacks existed lacks the key that now holds {})."""
    value = flat.get(key, "(unset)")
    return "(unset)" if value == {} else value
