"""The labels a user may give their recordings (``data.labels``): a CSV with a ``recording`` column and either
``p1`` and ``p2`` (1/s, 1/s^2) or the seat's ``c3``, ``k3`` and ``m3`` (N s/m, N/m, kg), one row per recording of
data.path. Bad rows raise ConfigError, one line naming the file, the row and what is allowed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from hybrid_sysid.core.checks import Shown, bad

KEY = "data.labels"
FORMS = (("p1", "p2"), ("c3", "k3", "m3"))


def read_labels(path, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """((n, 2) p1, p2 and (n,) m3, NaN where not given) of the recordings ``names``, in their order, from the
    labels file ``path``: every recording labelled once, no label of a recording data.path lacks."""
    path = Path(str(path)).expanduser()
    if not path.is_file():
        bad(KEY, Shown(str(path)), "a CSV file of labels that exists (columns recording, p1, p2 or c3, k3, m3)")
    try:
        df = pd.read_csv(path, skipinitialspace=True, converters={"recording": str})
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        bad(KEY, Shown(str(path)), f"a file that can be read as CSV ({type(exc).__name__}: {exc})")
    form = next((f for f in FORMS if all(c in df.columns for c in f)), None)
    if "recording" not in df.columns or form is None:
        bad(
            KEY,
            Shown(str(path)),
            f"columns recording and p1, p2 (or c3, k3, m3); its columns: {', '.join(map(str, df.columns))}",
        )
    values = {}
    for c in form + (("m3",) if "m3" in df.columns and form == FORMS[0] else ()):
        column = pd.to_numeric(df[c], errors="coerce").to_numpy(np.float64)
        wrong = np.flatnonzero(~(np.isfinite(column) & (column > 0)))
        if wrong.size:
            row = wrong[0]
            bad(f"{KEY} = {path}: column {c} in data row {row + 1}", df[c].iloc[row], "a finite number > 0")
        values[c] = column
    if form == FORMS[0]:
        p = np.stack([values["p1"], values["p2"]], axis=1)
        m3 = values.get("m3", np.full(len(df), np.nan))
    else:
        m3 = values["m3"]
        p = np.stack([values["c3"] / m3, values["k3"] / m3], axis=1)
    rows: dict[str, int] = {}
    known = set(names)
    for i, name in enumerate(df["recording"]):
        if name in rows:
            bad(
                f"{KEY} = {path}: recording {name!r} in data row {i + 1}",
                Shown(f"also in row {rows[name] + 1}"),
                "one row per recording",
            )
        if name not in known:
            bad(
                f"{KEY} = {path}: recording {name!r} in data row {i + 1}",
                Shown("a name data.path does not hold"),
                "the names of data.path's recordings (a file's recording column, else its name)",
            )
        rows[name] = i
    unlabelled = [n for n in names if n not in rows]
    if unlabelled:
        more = f" and {len(unlabelled) - 1} more" if len(unlabelled) > 1 else ""
        bad(KEY, Shown(f"{path}, without recording {unlabelled[0]!r}{more}"), "a row for every recording of data.path")
    order = np.array([rows[n] for n in names], dtype=np.int64)
    return p[order], m3[order]
