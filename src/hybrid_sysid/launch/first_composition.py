"""A single run's values refused at Hydra's first composition of the config, not its second.

Hydra 1.3 composes a command's config twice before any callback sees it: once to read ``hydra.mode`` (its
``Hydra.get_mode``; hydra issue 3440) and once for the run. A refused value waited for both: on an AMD EPYC,
medians of five, 1.16-1.31 s of CPU before, 1.03-1.10 s with the first composition checked, 10-16% less; an
evaluation of a directory that holds no run 1.09 s before, 0.88 s after (benchmarks/README.md, "a command's
start"). Hydra has no public hook between the two, so ``get_mode`` is wrapped:
a library's private internals, for that share of the time a user waits for a refusal. The wrapper composes as
Hydra's own does and runs the cheap value checks on it when the command is a single run; the preflight of the run
(hybrid_sysid.launch.job.Preflight) checks everything again on the second composition, so a valid config pays
nothing but those checks twice (milliseconds), and a Hydra without ``get_mode`` is left as it is. A config that does
not compose at all (an unknown key, a value of the wrong type) fails the first composition as it would fail the
second, so its error ends the command there: 1.01 -> 0.85 s of CPU for an unknown key on the AMD EPYC.
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from typing import Any, Callable, Iterator

from omegaconf import DictConfig


@contextmanager
def single_runs_checked_early(check: Callable[[DictConfig], None]) -> Iterator[None]:
    """Within: ``check`` (which exits the command on a refusal) runs on the config Hydra composes to read the mode,
    when neither the command line (``-m``, ``--multirun``: sweep_asked) nor the config asks for a sweep. Hydra is
    as it was after, so another command in the same process (a test's) composes unchecked."""
    try:
        from hydra._internal.hydra import Hydra  # private: the only code between the two compositions
        from hydra.types import RunMode
    except ImportError:
        yield
        return
    original = getattr(Hydra, "get_mode", None)
    if original is None:
        yield
        return

    def get_mode(self, config_name: str | None, overrides: list[str]) -> Any:
        try:  # as Hydra's own: composed for a sweep, sweep values not yet checked; a failure is the run's to report
            cfg = self.compose_config(
                config_name=config_name,
                overrides=overrides,
                with_log_configuration=False,
                run_mode=RunMode.MULTIRUN,
                validate_sweep_overrides=False,
            )
            mode = cfg.hydra.mode
        except Exception as exc:  # noqa: BLE001 - Hydra's get_mode returns None alike, and the second composition says why
            if fails_alike(exc, overrides):
                raise  # the second would fail alike: its one line (launch.process) without composing again
            return None
        if mode != RunMode.MULTIRUN and not sweep_asked(sys.argv[1:]):
            check(cfg)
        return mode

    Hydra.get_mode = get_mode
    try:
        yield
    finally:
        Hydra.get_mode = original


def sweep_asked(argv: list[str]) -> bool:
    """-m, --multirun or a prefix of it, which Hydra's argument parser takes for the whole (``--multi``)."""
    return any(a == "-m" or (len(a) > 2 and "--multirun".startswith(a)) for a in argv)


def fails_alike(exc: Exception, overrides: list[str]) -> bool:
    """Whether the run's own composition would fail as the first one did with ``exc``: a composition's error
    (config.composition) of a command with no sweep (by -m or a value list), since the first composes for a sweep
    without checking sweep values, and a single run's composition refuses a value list before anything else."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from hybrid_sysid.config.composition import composition_error

    if sweep_asked(sys.argv[1:]) or composition_error(exc) is None:
        return False
    try:
        return not any(o.is_sweep_override() for o in OverridesParser.create().parse_overrides(overrides))
    except Exception:  # noqa: BLE001 - an override that does not parse fails alike in both compositions
        return True
