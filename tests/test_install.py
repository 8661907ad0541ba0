"""The package carries its configs: a wheel installed (not editable) into a fresh virtual environment runs from
an empty directory and writes outputs/ there."""

import json
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow  # builds a wheel and a virtual environment: a minute or two


def test_wheel_installs_and_runs_from_an_empty_directory(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels), str(ROOT)],
        check=True,
        timeout=600,
    )
    (wheel,) = wheels.glob("hybrid_sysid-*.whl")
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    py = venv / "bin" / "python"
    # the dependencies come from this environment (a .pth adds its site-packages after the new one's), so the
    # test needs no network; the package itself comes only from the wheel
    site = subprocess.run(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    Path(site, "parent_env.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps", str(wheel)], check=True, timeout=600)

    work = tmp_path / "empty"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "HYBRID_SYSID_CACHE")}
    where = subprocess.run(
        [str(py), "-c", "import hybrid_sysid; print(hybrid_sysid.__file__)"],
        cwd=work,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    assert str(venv) in where  # the wheel's copy, not the source checkout
    proc = subprocess.run(
        [str(venv / "bin" / "hybrid-sysid"), "data=tiny", "trainer=debug", "trainer.progress_bar=false"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (record,) = (work / "outputs" / "runs").glob("*/metrics.json")
    assert json.loads(record.read_text())["status"] == "completed"
    assert (work / "outputs" / ".cache").is_dir()  # the dataset cache lands under the working directory too
