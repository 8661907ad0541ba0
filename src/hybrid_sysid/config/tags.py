"""``tags``: a user's labels of a run (lightning-hydra-template's convention, ``tags=[baseline,dt2ms]``), recorded in
metrics.json and sent to the experiment trackers. Checked before any work, so no tracker refuses one at the end."""

from __future__ import annotations

import re
from collections.abc import Sequence

from hybrid_sysid.core.checks import bad

TAGS_MAX = 20  # tags per run
TAG_LENGTH = 64  # characters per tag: a label, not a note
# letters, digits and . _ - / : (no comma, which joins them in a tracker's one text field, and no space)
TAG = re.compile(rf"[\w./:-]{{1,{TAG_LENGTH}}}")
ALLOWED = (
    f"a list of at most {TAGS_MAX} tags, each 1 to {TAG_LENGTH} letters, digits or . _ - / : "
    "(e.g. tags=[baseline,dt2ms])"
)


def check_tags(tags) -> list[str]:
    """The tags as a list of strings; ConfigError naming ``tags`` when they are no list of short labels."""
    if tags is None:
        return []
    if isinstance(tags, (str, bytes)) or not isinstance(tags, Sequence):
        bad("tags", tags, ALLOWED)
    values = list(tags)
    if len(values) > TAGS_MAX or not all(isinstance(t, str) and TAG.fullmatch(t) for t in values):
        bad("tags", values, ALLOWED)
    return values


def joined(tags) -> str:
    """The tags as one text field (an MLflow tag, TensorBoard's HPARAMS column): ``baseline,dt2ms``."""
    return ",".join(str(t) for t in tags or ())
