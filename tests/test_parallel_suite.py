"""The suite under pytest-xdist (``pytest -n 2``): a fixture of the whole test run is built once for all workers,
and a process started early runs once, in one worker, whatever worker reads it (tests/helpers/shared.py and
started_early.py). A small test run of its own, in a process of its own, with the helpers these use."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("xdist", reason="pytest-xdist is not installed (the test extra installs it)")

HELPERS = Path(__file__).parent  # tests/: where `helpers` is imported from

CONFTEST = """
import os
import pytest
from helpers.shared import WORKER, built_once
from helpers.started_early import started_early

pytest_plugins = ["helpers.started_early"]


def note(what):
    with open(os.environ["RAN_LOG"], "a") as log:  # one line a write: appends from two processes do not mix
        log.write(f"{what} {WORKER}\\n")


@pytest.fixture(scope="session")
def built(tmp_path_factory):
    def build(path):
        note("built")
        path.mkdir()
        (path / "value").write_text("42")

    return built_once(tmp_path_factory, "built", build)


@started_early
def first(tmp, env, built):
    note("first")
    return "first", (built / "value").read_text(), tmp


@started_early
def second(tmp, env):
    note("second")
    return "second"


@started_early
def refused(tmp, env):
    note("refused")
    pytest.skip("nothing to run here")


@started_early
def broken(tmp, env):
    note("broken")
    raise ValueError("the process failed")
"""

TESTS = """
import pytest


@pytest.mark.parametrize("i", range(3))
def test_first(first, built, i):
    assert first[:2] == ("first", "42") and first[2].is_dir() and (built / "value").read_text() == "42"


@pytest.mark.parametrize("i", range(3))
def test_second(second, i):
    assert second == "second"


def test_refused(refused):
    pass


def test_broken(broken):
    pass
"""


def test_two_workers_build_once_and_run_each_process_once(tmp_path):
    (tmp_path / "conftest.py").write_text(CONFTEST)
    (tmp_path / "test_readers.py").write_text(TESTS)
    log = tmp_path / "ran.log"
    env = {**os.environ, "PYTHONPATH": str(HELPERS), "RAN_LOG": str(log)}
    # --dist each: every worker runs every test, so each reads what the other worker ran as well as its own.
    # --basetemp: a numbered directory beside this run's would make pytest delete the oldest of those, maybe a
    # whole suite's (this test took 43 s instead of 4 s right after one)
    args = ["-n", "2", "--dist", "each", "-p", "no:cacheprovider", "-q", "-rs", f"--basetemp={tmp_path / 'tmp'}"]
    done = subprocess.run(
        [sys.executable, "-m", "pytest", *args],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    out = done.stdout + done.stderr
    # the skip and the error reach the readers in both workers: the error as each one's error in setup
    assert done.returncode == 1 and all(part in out for part in ("12 passed", "2 skipped", "2 errors")), out
    assert "SKIPPED [2] test_readers.py" in out and "nothing to run here" in out, out[-3000:]
    assert "started early in another worker, failed there" in out, out[-3000:]
    assert out.count("ValueError: the process failed") >= 2, out[-3000:]
    ran = sorted(log.read_text().splitlines())
    # each once; the k-th function (in the order of first readers) in worker k modulo 2
    assert ran == ["broken gw1", "built gw0", "first gw0", "refused gw0", "second gw1"], ran
