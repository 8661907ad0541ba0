"""Starting is cheap: ``hybrid-sysid --help`` and the refusals that come before any work load neither Lightning,
torch, scipy.signal nor numba (seconds of CPU between them; the package docstring lists what is deferred and why),
and those of run, eval and report load neither pandas nor matplotlib. The commands run as their console scripts
would, in a new interpreter that has loaded nothing yet."""

import json
import os
import subprocess
import sys

import pytest

HEAVY = ("lightning", "torch", "scipy.signal", "numba")
REPORTING = ("pandas", "matplotlib")  # the report's tables and figures: no refusal before predict's file needs them
# each command's main() as its console script calls it, one after the other in one new process: a module any of
# them loaded is still in sys.modules at the end. A control then loads the dataset kernel, which needs numba, so
# the probe is seen to find a heavy module when one is loaded.
PROBE = """
import json, os, sys
from hydra.core.global_hydra import GlobalHydra
from hybrid_sysid.cli import evaluate, predict, report, train
from hybrid_sysid.launch.process import PROCESS

HEAVY, REPORTING = {heavy!r}, {reporting!r}
codes, seen = {{}}, {{}}
for name, main, args in [
    ("help", train.main, ["--help"]),
    ("max_steps", train.main, ["trainer.max_steps=-1"]),
    ("objective", train.main, ["objective=nonexistent"]),
    ("net_value", train.main, ["estimator=anchored_cross_segment", "model.net.blend=3"]),
    ("objective_value", train.main, ["objective=cross_segment", "objective.target=xx"]),
    ("window", train.main, ["data.window=8"]),
    ("report", report.main, ["missing_sweep"]),
    ("eval", evaluate.main, ["run=no_run"]),
    ("predict", predict.main, ["run=no_run", "input=missing.csv"]),
]:
    sys.argv = [name, *args]
    try:
        codes[name] = main() or 0
    except SystemExit as exc:
        codes[name] = exc.code
    PROCESS.reset()
    GlobalHydra.instance().clear()
    seen[name] = sorted(m for m in REPORTING if m in sys.modules)
loaded = sorted(m for m in HEAVY if m in sys.modules)
import hybrid_sysid.data.cache
control = sorted(m for m in HEAVY if m in sys.modules)
found = {{"codes": codes, "seen": seen, "loaded": loaded, "control": control, "left": os.listdir(".")}}
print("PROBE " + json.dumps(found))
"""


def test_help_and_refusals_before_work_load_no_heavy_module(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}  # as a user has it
    env["HYBRID_SYSID_CACHE"] = str(tmp_path / "cache")
    proc = subprocess.run(
        [sys.executable, "-c", PROBE.format(heavy=HEAVY, reporting=REPORTING)],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,  # a hang guard only
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    found = json.loads(proc.stdout.rsplit("PROBE ", 1)[1])
    assert "usage: hybrid-sysid [-m] [key=value ...]" in proc.stdout  # the help was printed, not refused
    refused = ("max_steps", "objective", "net_value", "objective_value", "window", "predict", "report", "eval")
    assert found["codes"] == {"help": 0, **dict.fromkeys(refused, 2)}
    values = ("error: model.net.blend = 3", "error: objective.target = 'xx'", "error: data.window = 8")
    for line in (
        "error: trainer.max_steps = -1",
        "error: objective",
        *values,
        "missing.csv",
        "missing_sweep",
        "no_run",
    ):
        assert line in proc.stderr, proc.stderr[-3000:]
    assert found["loaded"] == [], found
    assert found["seen"]["eval"] == [], found  # every command before predict, cumulatively
    assert "numba" in found["control"], found  # the probe sees a heavy module once one is loaded
    assert found["left"] == [] and not (tmp_path / "cache").exists()


@pytest.mark.parametrize("overrides", [[], ["experiment=robustness"], ["car=soft_seat", "+data.x=1"]])
def test_help_in_one_composition_is_hydras_own_help(tmp_path, cli_in_process, overrides):
    """hybrid-sysid --help (config.help) prints what Hydra's own help path prints, groups and options alike."""
    from hybrid_sysid.cli.train import hydra_main, main
    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.config.help import quick_help
    from hybrid_sysid.launch.process import console_main

    code, out, _ = cli_in_process(main, *overrides, "--help", cwd=tmp_path)
    hydras = cli_in_process(lambda: console_main(hydra_main, sys.argv[1:]), *overrides, "--help", cwd=tmp_path)
    quick = quick_help([*overrides, "--help"], CONF_DIR, "config")  # the command's own path, not Hydra's
    assert quick is not None and (code, out) == (0, quick + "\n") == hydras[:2]
    assert "\nmodel: anchored, fast_cnn, paper_cnn\n" in quick and "hydra/" not in quick


def test_help_with_an_option_that_does_not_exist_is_hydras_one_line_refusal(tmp_path, cli_in_process):
    from hybrid_sysid.cli.train import main

    code, out, err = cli_in_process(main, "objective=nonexistent", "--help", cwd=tmp_path)
    assert code == 2 and out == "" and err.startswith("error: objective") and len(err.strip().splitlines()) == 1
