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
