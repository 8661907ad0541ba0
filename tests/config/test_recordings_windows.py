"""evaluation.windows with data=recordings: the range of data.spec.check_eval_windows (K in [1, the window starts
a recording offers]), taken on the shortest recording and named in the one-line refusal."""

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.config import validate
from hybrid_sysid.core.checks import ConfigError

from helpers.recordings import write_folder

WINDOW = 200


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Six recordings of 600 steps and one of 450: the shortest offers 450 - 200 + 1 = 251 window starts."""
    rng = np.random.default_rng(0)
    folder = tmp_path_factory.mktemp("files")
    write_folder(folder, *rng.standard_normal((2, 6, 600)))
    short = pd.DataFrame({"time": 0.005 * np.arange(450), "seat_acc": rng.standard_normal(450), "body_acc": 0.0})
    short.to_csv(folder / "short.csv", index=False)
    return folder


@pytest.mark.parametrize("windows, ok", [("[1,251]", True), ("[252]", False), ("[0]", False), ("[]", False)])
def test_k_is_refused_beyond_the_shortest_recordings_window_starts(make_cfg, folder, windows, ok):
    cfg = make_cfg(
        "data=recordings",
        f"data.path={folder}",
        f"data.window={WINDOW}",
        "objective=hybrid",
        f"evaluation.windows={windows}",
    )
    if ok:
        validate(cfg)
        return
    with pytest.raises(ConfigError) as caught:
        validate(cfg)
    assert caught.value.key == "evaluation.windows"
    assert caught.value.allowed.startswith(f"a non-empty list of K in [1, {450 - WINDOW + 1}]: the window starts")
