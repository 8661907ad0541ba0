"""experiment=tuned's searches as a table: per job (objective), the validation figure of the default values
(trial 0) and of the best trial, and the best values (hybrid_sysid.experiments.tuned writes them to
<job>/search/best.yaml)."""

from __future__ import annotations

from pathlib import Path

import yaml

from hybrid_sysid.report.tables import markdown_table


def searches(paths) -> list[tuple[str, dict]]:
    """(job directory, best.yaml) for every search at or below paths, in path order."""
    paths = [Path(paths)] if isinstance(paths, (str, Path)) else [Path(p) for p in paths]
    found = sorted({f.resolve() for p in paths for f in p.rglob("search/best.yaml")})
    return [(f.parent.parent.name, yaml.safe_load(f.read_text())) for f in found]


def _g(value) -> str:
    return "n/a" if value is None else f"{value:.4g}" if isinstance(value, float) else str(value)


def tuning_markdown(paths) -> str:
    """A markdown table of the searches; the job's own overrides (those not shared by every job) label its row.
    An empty string when there is none."""
    found = searches(paths)
    if not found:
        return ""
    shared = set.intersection(*(set(b.get("overrides") or []) for _, b in found))
    params = list(dict.fromkeys(k for _, b in found for k in b["best"]["params"]))
    header = ["job", "monitor", "trials", "default (trial 0)", "best", "best trial", *params]
    rows = []
    for job, b in found:
        label = " ".join(o for o in b.get("overrides") or [] if o not in shared) or job
        rows.append(
            [
                label,
                b.get("monitor", ""),
                f"{b['completed']}/{b['n_trials']}",
                _g(b["default"]["value"]),
                _g(b["best"]["value"]),
                str(b["best"]["trial"]),
                *(_g(b["best"]["params"].get(k)) for k in params),
            ]
        )
    return (
        "Searches: the validation figure each objective's model selection uses (lower is better), of its "
        "default values and of its best trial, and the best trial's values.\n\n"
        + markdown_table(header, rows, n_left=2)
    )
