"""A received run's saved config is data (hybrid_sysid.runs.received): an interpolation that reads the environment
or files is never resolved and its value never shown, and the run's cache and output paths are this machine's, so
a received one is never written to."""

import re

import numpy as np
import pytest

from helpers.received import received
from helpers.tree import snapshot

SECRET = "hunter2-do-not-show"


@pytest.fixture
def recording(tmp_path):
    path = tmp_path / "drive.csv"
    t = np.arange(2000) * 0.005
    np.savetxt(
        path, np.c_[t, np.sin(9 * t), np.cos(7 * t)], delimiter=",", header="time,seat_acc,body_acc", comments=""
    )
    return path


def command(name, run, tmp_path, recording):
    """(main, arguments) of the command reading the received run."""
    if name == "predict":
        from hybrid_sysid.cli.predict import main

        return main, [f"run={run}", f"input={recording}"]
    if name == "eval":
        from hybrid_sysid.cli.evaluate import main

        return main, [f"run={run}", f"hydra.run.dir={tmp_path / 'ev'}"]
    from hybrid_sysid.cli.train import main

    tiny = ["data=tiny", "trainer=debug", "trainer.max_steps=2", "trainer.progress_bar=false"]
    return main, [*tiny, f"init_from={run}", f"hydra.run.dir={tmp_path / 'tr'}"]


@pytest.mark.parametrize("name", ["predict", "eval", "init_from"])
def test_an_environment_variable_in_a_received_config_is_never_read_or_shown(
    tiny_run, tiny_cache, tmp_path, recording, cli_in_process, name
):
    """${oc.env:SECRET} as data.n_roads: once resolved, and its value echoed in the error line. Now one line naming
    the key and the resolver, exit 2, nothing written."""
    run = received(tiny_run, tmp_path, "  n_roads: 6", "  n_roads: ${oc.env:SECRET}")
    main, args = command(name, run, tmp_path, recording)
    before = snapshot(tmp_path)
    env = {"SECRET": SECRET, "HYBRID_SYSID_CACHE": tiny_cache}
    code, out, err = cli_in_process(main, *args, cwd=tmp_path, env=env)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err[-2000:]
    assert "data.n_roads holds an interpolation through oc.env" in lines[0], lines[0]
    assert SECRET not in out + err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "value, words",
    [
        ("${oc.decode:${oc.env:SECRET}}", "holds an interpolation through oc.decode"),
        ("${hydra_subdir:/}", "holds an interpolation through hydra_subdir"),  # reads a record on disk
        ("${${oc.env:SECRET}:1}", "holds an interpolation through a resolver named by an interpolation"),
        ("${oc.env:SECRET", "GrammarParseError"),  # OmegaConf refuses it as it reads the file
    ],
)
def test_any_resolver_that_reads_more_than_the_config_is_refused(
    tiny_run, tmp_path, recording, cli_in_process, value, words
):
    run = received(tiny_run, tmp_path, "  n_roads: 6", f"  n_roads: '{value}'")
    main, args = command("predict", run, tmp_path, recording)
    code, out, err = cli_in_process(main, *args, cwd=tmp_path, env={"SECRET": SECRET})
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert f"data.n_roads {words}" in err or words in err and "data.n_roads" in err, err
    assert SECRET not in out + err


def test_a_received_cache_and_paths_are_never_written(tiny_run, tiny_cache, tmp_path, cli_in_process):
    """A received config whose data.cache_dir and paths point elsewhere (here a folder beside it): eval simulates
    into, or reads from, this machine's cache, and writes nothing there."""
    from hybrid_sysid.cli.evaluate import main

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    run = received(tiny_run, tmp_path, "  root: outputs", f"  root: {elsewhere}")
    config = run / ".hydra" / "config.yaml"
    text = config.read_text()
    # data.cache_dir (the first cache_dir, the data section's), then paths.cache_dir
    text = re.sub(r"\n  cache_dir: [^\n]*\n", f"\n  cache_dir: {elsewhere / 'c'}\n", text, count=1)
    text = text.replace("${oc.env:HYBRID_SYSID_CACHE,${paths.root}/.cache}", str(elsewhere / "p"))
    assert text.count(str(elsewhere)) == 3
    config.write_text(text)
    args = [f"run={run}", f"hydra.run.dir={tmp_path / 'ev'}"]
    code, out, err = cli_in_process(main, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 0, err[-2000:]
    assert list(elsewhere.iterdir()) == []
    assert (tmp_path / "ev" / "metrics.json").is_file()
