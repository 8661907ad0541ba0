"""hybrid-sysid-report under SIGTERM: one line, 128 + the signal's number, and no temporary file left where a
figure was being written (the default SIGTERM ended the process inside write_atomic, before its cleanup)."""

import signal
import subprocess
import sys

from helpers.evaluation_fakes import make_sweep

# the report in a child, which sends itself SIGTERM once a figure's temporary file is drawn, before it is renamed
CHILD = """
import os, signal, sys
import matplotlib.figure
from hybrid_sysid.cli.report import main

draw = matplotlib.figure.Figure.savefig

def savefig(self, path, *args, **kwargs):
    draw(self, path, *args, **kwargs)
    if ".robustness.png." in str(path):
        os.kill(os.getpid(), signal.SIGTERM)

matplotlib.figure.Figure.savefig = savefig
sys.exit(main(sys.argv[1:]))
"""


def test_a_sigterm_while_a_figure_is_written_is_one_line_and_leaves_no_temporary_file(tmp_path):
    sweep = make_sweep(tmp_path / "sweep", failed=False)
    proc = subprocess.run([sys.executable, "-c", CHILD, str(sweep)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 128 + signal.SIGTERM
    assert proc.stderr.splitlines()[-1].startswith("error: hybrid-sysid-report interrupted by SIGTERM")
    assert "Traceback" not in proc.stderr
    figures = sweep / "figures"
    assert not [p.name for p in figures.iterdir() if p.name.endswith(".tmp")]
    assert not (figures / "robustness.png").exists()  # the figure under way, never half there


def test_a_report_into_a_sweep_another_process_is_writing_is_refused(tmp_path, capsys):
    """A sweep still running holds its directory; a report there would write a table of its first jobs, racing
    with (or replacing) the sweep's own summary. It is refused in one line, nothing written; once the writer has
    ended, the same report writes."""
    from hybrid_sysid.cli.report import main
    from hybrid_sysid.runs.layout import WRITER_LOCK

    sweep = make_sweep(tmp_path / "sweep", failed=False)
    (sweep / WRITER_LOCK).touch()  # the lock file every run and sweep directory holds
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(sweep / WRITER_LOCK)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        assert main([str(sweep)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "another process is writing there" in err
        assert not (sweep / "summary.md").exists() and not (sweep / "figures").exists()
    finally:
        holder.kill()
        holder.wait()
    assert main([str(sweep)]) == 0 and (sweep / "summary.md").is_file()


# another process that holds a directory's writer lock, as a running sweep does (runs/locks.py), until killed
HOLD = """
import sys, time
from filelock import FileLock
lock = FileLock(sys.argv[1], timeout=0)
lock.acquire()
print("held", flush=True)
time.sleep(600)
"""
