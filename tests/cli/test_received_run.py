"""A received run directory is data: its saved config gets the checks of a command line before predict estimates
with it (hybrid_sysid.inference.loading), in one line, exit status 2, nothing written."""

import shutil

import numpy as np
import pytest

from helpers.estimator_run import predict
from helpers.tree import snapshot


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A recording sampled at twice the run's rate (data=tiny: dt 0.005 s), so resample=true has work to do."""
    path = tmp_path_factory.mktemp("recording") / "drive.csv"
    t = np.arange(4000) * 0.0025
    columns = np.c_[t, np.sin(9 * t), np.cos(7 * t)]
    np.savetxt(path, columns, delimiter=",", header="time,seat_acc,body_acc", comments="")
    return path


def received(tiny_run, tmp_path, line, replaced):
    """A copy of the trained run whose saved config has ``line`` (as saved, indented) replaced."""
    run = tmp_path / "received"
    shutil.copytree(tiny_run, run)
    config = run / ".hydra" / "config.yaml"
    text = config.read_text()
    assert f"\n{line}\n" in text
    config.write_text(text.replace(f"\n{line}\n", f"\n{replaced}\n"))
    return run


@pytest.mark.parametrize(
    "line, replaced, words",
    [
        ("  window: 200", "  window: 0", "data.window = 0 is not allowed"),  # was a reshape traceback
        ("  dt: 0.005", "  dt: 0", "data.dt = 0.0 is not allowed"),  # was a ZeroDivisionError with resample=true
    ],
)
def test_a_received_runs_values_get_a_command_lines_checks(
    tiny_run, tmp_path, recording, capsys, line, replaced, words
):
    run = received(tiny_run, tmp_path, line, replaced)
    before = snapshot(tmp_path, recording.parent)
    code, out, err = predict(capsys, f"run={run}", f"input={recording}", "resample=true")
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and f"run = {run}: {words}" in err, err
    assert snapshot(tmp_path, recording.parent) == before
