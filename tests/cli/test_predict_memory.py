"""hybrid-sysid-predict under an address-space limit (ulimit -v: RLIMIT_AS): a windows= whose windows exceed it is
one line and exit status 2 before anything that size is allocated, although free memory would hold them; nothing
is written. A real process, its limit set by itself after its imports (the interpreter and torch map about 1 GiB)."""

import subprocess
import sys

import numpy as np

from helpers.estimator_run import recordings

GIB = 2**30
# the child: its limit 1 GiB above what it has mapped once the command and the run are loaded, then the command
CHILD = """
import resource, sys
from hybrid_sysid.cli.predict import main
from hybrid_sysid.inference.loading import load_estimator
load_estimator(sys.argv[1])
mapped = next(int(x.split()[1]) * 1024 for x in open("/proc/self/status") if x.startswith("VmSize:"))
resource.setrlimit(resource.RLIMIT_AS, (mapped + 2**30, resource.getrlimit(resource.RLIMIT_AS)[1]))
main(sys.argv[2:])
"""


def test_windows_beyond_the_address_space_limit_are_one_line_and_status_2(tiny_run, est, tmp_path):
    """400000 windows of 2 x 200 steps need 2.39 GiB (8000 bytes each, 6400 beyond the first 4096): far below the
    free memory, far above the 1 GiB the limit leaves. Without the limit in the check the process died with a
    MemoryError traceback, exit 1."""
    n, k = 420_000, 400_000
    seat, body, _ = recordings(1, 1000, est.dt)
    np.savez(tmp_path / "long.npz", seat_acc=np.resize(seat[0], n), body_acc=np.resize(body[0], n), dt=est.dt)
    out = tmp_path / "out.csv"
    argv = [f"run={tiny_run}", f"input={tmp_path / 'long.npz'}", f"windows={k}", f"output={out}"]
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(tiny_run), *argv], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    need = k * 6400 + 4096 * 1600
    assert done.returncode == 2 and done.stdout == "", done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    head = f"hybrid-sysid-predict: error: input = {tmp_path / 'long.npz'}: windows = {k} is not allowed: 1 to "
    assert lines[0].startswith(head), lines
    assert f"{k} windows of 2 x 200 steps need {need / GIB:.3g} GiB of memory" in lines[0]
    assert lines[0].endswith(
        "GiB is available (the address-space limit (RLIMIT_AS, ulimit -v) less the address space in use)"
    ), lines
    available = float(lines[0].split(" and ")[-1].split(" GiB")[0])
    fit = int(lines[0][len(head) :].split()[0])
    # at most the 1 GiB left; the windows it allows fit in what it reports (to its 3 digits)
    assert 0 < available <= 1.0 and fit * 6400 + 4096 * 1600 <= available * GIB * 1.005, lines
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.npz"]  # no output, no temporary file


def test_running_out_of_memory_anyway_is_one_line_and_status_2(tiny_run, est, tmp_path, capsys, monkeypatch):
    """An allocation the windows' check cannot foresee (here the estimate itself raises MemoryError): one line, exit
    status 2, no output file."""
    from hybrid_sysid.inference.estimator import Estimator

    from helpers.estimator_run import predict

    def out_of_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(Estimator, "predict", out_of_memory)
    seat, body, _ = recordings(1, 400, est.dt)
    np.savez(tmp_path / "rec.npz", seat_acc=seat[0], body_acc=body[0], dt=est.dt)
    code, out, err = predict(capsys, f"run={tiny_run}", f"input={tmp_path / 'rec.npz'}", f"output={tmp_path / 'o.csv'}")
    assert code == 2 and out == "" and len(err.splitlines()) == 1, err
    assert err.startswith("hybrid-sysid-predict: error: out of memory: ") and "windows=" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.npz"]
