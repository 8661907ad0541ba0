"""A researcher's package of plugins (tests/plugins/example, its own pyproject.toml) installed with pip and used
from the command line, as docs/extending.md shows: its network and objective in a sweep beside a built-in
objective, a row of the table each, its objective the one that trained; and its runs opened where it is not
installed, which name the package to install.

pip installs it into a folder of the test's own (``--target``), which the sweep's processes find on PYTHONPATH:
this process and the environment never see it, so no other test does, and nothing is left to uninstall."""

import json
import os
import shutil
import subprocess
import sys
from importlib.util import find_spec
from pathlib import Path

import pytest

from helpers import app_process
from helpers.started_early import started_early

pytestmark = pytest.mark.integration

EXAMPLE = Path(__file__).resolve().parents[1] / "plugins" / "example"
STEPS = 6
SWEEP = [
    "-m",
    "objective=labelled,relative_l2",
    "model=tiny_net",  # the package's configs are options without hydra.searchpath (hybrid_sysid.configs)
    "data=tiny",
    "trainer=debug",
    f"trainer.max_steps={STEPS}",
    "trainer.eval_every_n_steps=3",
]
PACKAGE = "hybrid-sysid-example-plugin"


@started_early
def plugin_sweep(tmp, env, tiny_cache):
    """(the sweep's process, its directory, the folder the package is installed in)."""
    if not (find_spec("setuptools") and (find_spec("setuptools.command.bdist_wheel") or find_spec("wheel"))):
        pytest.skip("pip builds the example package offline, with this environment's setuptools (>= 70.1, or wheel)")
    source, site = tmp / "source", tmp / "site"
    shutil.copytree(EXAMPLE, source)  # the build writes build/ and *.egg-info beside the sources, not in the tests
    pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--no-index"]
    installed = subprocess.run([*pip, "--target", site, source], capture_output=True, text=True, timeout=300)
    assert installed.returncode == 0, installed.stderr[-2000:]
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(site), env.get("PYTHONPATH")) if p)
    proc = app_process.run_app(tmp, *SWEEP, f"hydra.sweep.dir={tmp / 'sw'}", cache=tiny_cache, env=env)
    return proc, tmp / "sw", site


def job_of(sweep: Path, objective: str) -> Path:
    return next(
        p.parent
        for p in sweep.glob("*/metrics.json")
        if f"objective={objective}" in json.loads(p.read_text())["overrides"]
    )


def test_the_plugins_train_in_a_sweep_beside_a_built_in_objective(plugin_sweep):
    import torch

    proc, sweep, _ = plugin_sweep
    assert proc.returncode == 0, proc.stderr[-2000:]
    table = [ln.split("|") for ln in (sweep / "summary.md").read_text().splitlines() if ln.startswith("| ")]
    rows = {cells[1].strip(): cells for cells in table[1:]}
    assert [c.strip() for c in rows.pop("Cramér-Rao bound")[-3:-1]] == ["", ""]  # the bound: no seeds, no failures
    assert set(rows) == {"labelled", "relative_l2"}
    for objective in rows:
        job = job_of(sweep, objective)
        record = json.loads((job / "metrics.json").read_text())
        assert record["status"] == "completed" and record["steps"] == STEPS
        # the table's first cell: the record's test error (one seed: the mean is the value)
        first = next(r for r in record["results"] if (r["split"], r["noise_std"], r["parameter"]) == ("test", 0, "p1"))
        assert rows[objective][2].strip().strip("*").split(" ")[0] == f"{100 * first['mean_rel_dev']:.2f}"
        net = record["plugins"]["model.net"]
        assert (net["class"], net["entry_point"], net["package"]) == (
            "hybrid_sysid_example_plugin.networks.TinyNet",
            "hybrid_sysid.networks:tiny_net",
            PACKAGE,
        )
        state = torch.load(job / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=False)["state_dict"]
        if objective == "relative_l2":
            # the plugin's objective scored every training batch: one a step, as trainer.max_steps asked
            assert state["objective.scored"].item() == STEPS
            assert record["plugins"]["objective"]["entry_point"] == "hybrid_sysid.objectives:relative_l2"
        else:
            assert "objective.scored" not in state and "objective" not in record["plugins"]


def test_a_run_made_with_the_plugin_names_the_package_where_it_is_missing(
    plugin_sweep, tmp_path, monkeypatch, cli_in_process
):
    from hybrid_sysid.cli.evaluate import main
    from hybrid_sysid.inference.inputs import InputError
    from hybrid_sysid.inference.loading import load_estimator

    _, sweep, site = plugin_sweep
    run = job_of(sweep, "relative_l2")
    words = (
        "model.net._target_ = 'hybrid_sysid_example_plugin.networks.TinyNet' is not allowed: ",
        f"entry point hybrid_sysid.networks:tiny_net of the package {PACKAGE} 0.1.0, not installed here",
        f"pip install {PACKAGE}",
    )
    with pytest.raises(InputError) as err:
        load_estimator(run)
    assert all(w in str(err.value) for w in words) and "\n" not in str(err.value)

    (tmp_path / "work").mkdir()
    code, out, err = cli_in_process(main, f"run={run}", cwd=tmp_path / "work")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and all(w in lines[0] for w in words), err[-2000:]
    assert list((tmp_path / "work").iterdir()) == []

    monkeypatch.syspath_prepend(str(site))  # installed: the same run opens, with the plugin's network
    try:
        estimator = load_estimator(run)
        assert type(estimator.net).__name__ == "TinyNet"
    finally:
        for name in [m for m in sys.modules if m.startswith("hybrid_sysid_example_plugin")]:
            del sys.modules[name]
