"""Packages installed for a test alone, in a folder of its own that it puts on sys.path (or a process's PYTHONPATH),
so that no other test sees them and nothing is left to uninstall: ``install_package`` writes one the way pip leaves
it (its files and a ``<name>.dist-info`` with METADATA and entry_points.txt); ``install_example`` has pip install
the example package of plugins (tests/plugins/example), as a researcher installs theirs."""

import shutil
import subprocess
import sys
from importlib.util import find_spec
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "plugins" / "example"


def install_package(site: Path, dist: str, files: dict, entry_points: dict) -> Path:
    """``files`` ({path relative to ``site``: text}) and ``entry_points`` ({group: {name: value}}) of the package
    ``dist`` 0.1.0, in ``site``; returns ``site``."""
    info = site / f"{dist.replace('-', '_')}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1.0\n")
    groups = [f"[{group}]\n" + "".join(f"{n} = {v}\n" for n, v in eps.items()) for group, eps in entry_points.items()]
    (info / "entry_points.txt").write_text("\n".join(groups))
    for path, text in files.items():
        (site / path).parent.mkdir(parents=True, exist_ok=True)
        (site / path).write_text(text)
    return site


def install_example(tmp: Path) -> Path:
    """The folder pip installed the example package into (``--target``), built offline from a copy of its
    sources (the build writes build/ and *.egg-info beside them, not in the tests)."""
    if not (find_spec("setuptools") and (find_spec("setuptools.command.bdist_wheel") or find_spec("wheel"))):
        pytest.skip("pip builds the example package offline, with this environment's setuptools (>= 70.1, or wheel)")
    source, site = tmp / "example_source", tmp / "example_site"
    shutil.copytree(EXAMPLE, source, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--no-index"]
    installed = subprocess.run([*pip, "--target", site, source], capture_output=True, text=True, timeout=300)
    assert installed.returncode == 0, installed.stderr[-2000:]
    return site
