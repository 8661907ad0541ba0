"""Where a table's numbers come from, stated under its heading on a results page: the command that re-creates each
sweep behind it, the commit its runs were made at, and the processor they ran on.

The command is Hydra's record of the command line: a sweep directory's multirun.yaml holds the overrides given
(``hydra.overrides.task``, and ``hydra.overrides.hydra`` but where the runs were written, which changes no
number); a single run's are its record's ``overrides``. The commit (``git_commit``, ``git_dirty``) and the
processor's model name (``cpu``) are fields of each run's record (training/run.py writes them). The numbers of one
command differ in their last digits between kinds of processor (docs/reliability/reproducibility.md), so the page
names the kind.

The block is three list items, one per fact; a value that differs between the runs of a table is listed with the
number of runs that have it::

    - command: `hybrid-sysid experiment=robustness`
    - commit: `8d9477c` (dirty)
    - CPU: Intel(R) Xeon(R) Processor

``read_provenance`` reads it back, and ``page_sections`` and ``markdown_rows`` read a page's sections and tables,
so a test can check a page against its runs without copying a number.
"""

from __future__ import annotations

import math
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.core.overrides import parse_override, parse_overrides
from hybrid_sysid.report.collect import config_value
from hybrid_sysid.runs.reading import read_yaml
from hybrid_sysid.runs.rundir import DamagedFile, RunDir
from hybrid_sysid.runs.sweepdir import SweepDir, sweep_dir_of

# the overrides that only say where runs are written: left out of a command (they would name this machine's paths)
LOCATION_KEYS = ("hydra.sweep.dir", "hydra.sweep.subdir", "hydra.run.dir")
APPS = {"config": "hybrid-sysid", "eval": "hybrid-sysid-eval"}  # primary config -> the command that composes it
SHORT = 7  # characters of a commit shown: git's default abbreviation
NOT_RECORDED = "not recorded"


@dataclass(frozen=True)
class Provenance:
    """commands: (command line, the names of the sweep directories it made, or of the single runs, joined by ", ");
    commits: (short hash or None when not recorded, dirty or None, number of runs); cpus: (model name or None,
    number of runs). A fact with one value has one entry."""

    commands: tuple[tuple[str, str], ...]
    commits: tuple[tuple[str | None, bool | None, int], ...]
    cpus: tuple[tuple[str | None, int], ...]


def _app(config_name) -> str:
    return APPS.get(str(config_name), APPS["config"])


def _preset_is_multirun(name: str) -> bool:
    """Whether conf/experiment/<name>.yaml sets hydra.mode: MULTIRUN, so its command needs no -m."""
    return config_value(read_yaml(Path(CONF_DIR) / "experiment" / f"{name}.yaml"), "hydra.mode") == "MULTIRUN"


def command_line(app: str, overrides, multirun: bool = False) -> str:
    """The shell command: app, -m for a multirun whose experiment preset does not start one by itself, then the
    overrides as given (quoted for a POSIX shell where needed)."""
    overrides = [str(o) for o in overrides]
    presets = [
        o.value for o in parse_overrides(overrides) if o.key == "experiment" and o.value is not None and not o.deletes
    ]
    flag = multirun and not (presets and _preset_is_multirun(presets[-1]))
    return shlex.join([app, *(["-m"] if flag else []), *overrides])


def sweep_command(sweep_dir: Path) -> str | None:
    """The command line that started the sweep, from its multirun.yaml; None if the file cannot be read."""
    hydra = config_value(SweepDir(sweep_dir).saved_values(), "hydra")
    task = config_value(hydra, "overrides.task")
    if not isinstance(task, list):
        return None
    extra = [o for o in config_value(hydra, "overrides.hydra") or [] if parse_override(o).key not in LOCATION_KEYS]
    return command_line(_app(config_value(hydra, "job.config_name")), [*task, *extra], multirun=True)


def _run_command(run_dir: Path) -> str:
    """A single run's command line: its record's overrides (Hydra's task overrides: the command line's)."""
    run = RunDir(run_dir)
    try:
        overrides = (run.record() or {}).get("overrides") or run.overrides()
    except (DamagedFile, AttributeError):  # an unreadable record: Hydra's own copy of the overrides
        overrides = run.overrides()
    return command_line(_app(run.config_name()), overrides)


def _counts(values: list) -> list[tuple[object, int]]:
    """(value, number of times) in order of first appearance."""
    counts: dict = {}
    for v in values:
        counts[v] = counts.get(v, 0) + 1
    return list(counts.items())


def _known(value):
    """A record's field as read by collect: None for a missing one (NaN in the long form)."""
    return None if value is None or (isinstance(value, float) and math.isnan(value)) else value


def provenance(df: pd.DataFrame, root: Path, paths=()) -> Provenance:
    """The provenance of a table made from collect's long form ``df`` (runs named relative to ``root``). Commits
    and processors are those of the completed runs, the ones whose numbers are shown; commands are those of every
    run, one per sweep, in the order of ``paths`` (the directories the table was made from), then of the runs."""
    runs = df.drop_duplicates("run")
    commands: dict[str, dict[Path, None]] = {}  # command -> the sweeps (or single runs) it made, in order
    of_sweep: dict[Path, str | None] = {}  # each sweep's multirun.yaml is read once, not once per run
    for name in runs.run:
        run_dir = Path(root) / name
        sweep = sweep_dir_of(run_dir)
        if sweep is not None and sweep not in of_sweep:
            of_sweep[sweep] = sweep_command(sweep)
        command = of_sweep[sweep] if sweep is not None else None
        commands.setdefault(command or _run_command(run_dir), {})[sweep or run_dir] = None
    given = [Path(p).resolve() for p in paths]

    def rank(item) -> int:  # the first given path the command's first sweep lies in, at or above or below
        d = next(iter(item[1])).resolve()
        return next((i for i, p in enumerate(given) if d == p or p in d.parents or d in p.parents), len(given))

    done = runs[runs.status == "completed"]
    commits = []  # plain values: Series.map would give the missing ones back as NaN
    for commit, dirty in zip(map(_known, done.git_commit), map(_known, done.git_dirty)):
        commits.append((str(commit)[:SHORT], None if dirty is None else bool(dirty)) if commit else (None, None))
    cpus = [None if c is None else str(c) for c in map(_known, done.cpu)]
    return Provenance(
        commands=tuple((c, ", ".join(d.name for d in dirs)) for c, dirs in sorted(commands.items(), key=rank)),
        commits=tuple((c, d, n) for (c, d), n in _counts(commits)),
        cpus=tuple(_counts(cpus)),
    )


def _runs(n: int) -> str:
    return f"{n} run" + ("" if n == 1 else "s")


def provenance_lines(p: Provenance) -> list[str]:
    """The block under a table's heading (module docstring): a list item per fact, then a blank line."""
    several = len(p.commands) > 1
    # a table of several sweeps names each sweep beside its command, also when they share one
    named = several or any(", " in names for _, names in p.commands)
    commands = "; ".join(f"`{c}`" + (f" ({names})" if named else "") for c, names in p.commands)

    def commit(c, dirty, n, counted):
        text = NOT_RECORDED if c is None else f"`{c}`"
        notes = (["dirty"] if dirty else []) + ([_runs(n)] if counted else [])
        return text + (f" ({', '.join(notes)})" if notes else "")

    disagree = len(p.commits) > 1
    commits = "; ".join(commit(c, d, n, disagree) for c, d, n in p.commits) or "no completed run"
    cpus = "; ".join(
        (NOT_RECORDED if c is None else c) + (f" ({_runs(n)})" if len(p.cpus) > 1 else "") for c, n in p.cpus
    )
    return [
        f"- command{'s' * several}: {commands}",
        f"- commit{'s, which differ between the runs' * disagree}: {commits}",
        f"- CPU{'s' * (len(p.cpus) > 1)}: {cpus or 'no completed run'}",
        "",
    ]


_ITEM = re.compile(r"^- (command|commit|CPU)[^:]*: (.*)$")
_COUNT = re.compile(r"^(.*?)(?: \((dirty)?(?:, )?(?:(\d+) runs?)?\))?$")


def read_provenance(text: str) -> Provenance | None:
    """The provenance block at the start of a section's text (its heading's line excluded), as written by
    provenance_lines; None when the section does not start with one. Counts are 1 where the block gives none."""
    items = {}
    for line in text.strip("\n").splitlines():
        m = _ITEM.match(line)
        if m is None:
            break
        items[m.group(1)] = m.group(2)
    if set(items) != {"command", "commit", "CPU"}:
        return None
    commands = tuple(
        (m.group(1), m.group(2) or "") for m in re.finditer(r"`([^`]+)`(?: \(([^)]+)\))?", items["command"])
    )
    commits, cpus = [], []
    for part in items["commit"].split("; "):
        m = _COUNT.match(part)
        name = m.group(1)
        commit = name.strip("`") if name.startswith("`") else None
        commits.append((commit, None if commit is None else bool(m.group(2)), int(m.group(3) or 1)))
    for part in items["CPU"].split("; "):
        m = re.match(r"^(.*?)(?: \((\d+) runs?\))?$", part)
        cpus.append((None if m.group(1) == NOT_RECORDED else m.group(1), int(m.group(2) or 1)))
    return Provenance(commands, tuple(commits), tuple(cpus))


def page_sections(text: str, level: int = 2) -> list[tuple[str, str]]:
    """(heading, text up to the next heading of that level or above) for each heading of ``level`` (2: "## ")."""
    out, marks = [], "#" * level + " "
    for line in text.splitlines(keepends=True):
        if line.startswith(marks):
            out.append([line[len(marks) :].strip(), ""])
        elif out and re.match(rf"^#{{1,{level}}} ", line):
            out.append(None)  # a heading above this level ends the section
        elif out and out[-1] is not None:
            out[-1][1] += line
    return [(h, t) for h, t in (s for s in out if s is not None)]


def markdown_rows(text: str) -> list[dict[str, str]]:
    """The first markdown table in text as {header: cell} per row, cells stripped ("\\|" stays an escaped bar)."""
    lines = []
    for line in text.splitlines():
        if line.startswith("|"):
            lines.append(line)
        elif lines:
            break
    split = [[c.strip() for c in re.split(r"(?<!\\)\|", ln.strip()[1:-1])] for ln in lines]
    return [dict(zip(split[0], row)) for row in split[2:]]


def generated_sections(text: str) -> list[tuple[str, str]]:
    """The "## " sections of a results page that write_results made from runs: those after the hand-written notes
    (closed by "<!-- end of ... -->"), or every one on a page without notes."""
    end = list(re.finditer(r"^<!-- end of .* -->$", text, flags=re.M))
    return page_sections(text[end[-1].end() :] if end else text)


def sections_without_provenance(text: str) -> list[str]:
    """The generated sections of a results page whose table does not name where it comes from: no provenance
    block under the heading, no `hybrid-sysid...` command, or a run whose commit was not recorded. Each entry is
    the heading and what is missing."""
    out = []
    for heading, body in generated_sections(text):
        p = read_provenance(body)
        if p is None:
            out.append(f"{heading}: no provenance block under the heading")
            continue
        if not p.commands or not all(c.startswith("hybrid-sysid") for c, _ in p.commands):
            out.append(f"{heading}: no command line")
        if not p.commits or any(c is None or not re.fullmatch(r"[0-9a-f]{7,40}", c) for c, _, _ in p.commits):
            out.append(f"{heading}: a commit not recorded")
    return out
