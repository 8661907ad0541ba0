"""A single run's refused value ends the command after Hydra's first composition of the config, the one that reads
hydra.mode, not after the second (hybrid_sysid.launch.first_composition); a valid run and a sweep compose as Hydra
does on its own. Hydra's own composition is the reference: its calls are counted, not replaced."""

import pytest


@pytest.fixture
def compositions(monkeypatch):
    from hydra._internal.hydra import Hydra

    seen = []
    original = Hydra.compose_config

    def counted(self, *args, **kwargs):
        seen.append(kwargs.get("run_mode"))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Hydra, "compose_config", counted)
    return seen


@pytest.mark.parametrize(
    "args, words",
    [
        (["data.window=8"], "data.window = 8"),
        (["objective=cross_segment", "objective.target=xx"], "objective.target = 'xx'"),
        (["estimator=anchored_cross_segment", "model.net.blend=3"], "model.net.blend = 3"),
    ],
)
def test_a_refused_value_is_refused_after_one_composition(tmp_path, compositions, cli_in_process, args, words):
    from hydra._internal.hydra import Hydra

    from hybrid_sysid.cli.train import main

    before = Hydra.get_mode
    code, out, err = cli_in_process(main, *args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1, err
    assert len(compositions) == 1, compositions  # Hydra's reading of the mode, and nothing after it
    assert not (tmp_path / "run").exists()
    assert Hydra.get_mode is before  # put back: another command in this process composes as Hydra does


@pytest.mark.parametrize("flag", ["-m", "--multi"])  # Hydra's parser takes a prefix of --multirun for it
def test_a_sweep_is_not_checked_at_the_first_composition(tmp_path, compositions, cli_in_process, flag):
    """-m: the first composition is not checked (a swept value is not yet a value); Hydra composes again for the
    sweep, whose job refuses the value in its own record."""
    from hybrid_sysid.cli.train import main

    code, _, err = cli_in_process(
        main, flag, "trainer.max_steps=-1", f"hydra.sweep.dir={tmp_path / 'sweep'}", cwd=tmp_path
    )
    assert code != 0 and "1 of 1 job failed" in str(code) + err
    assert len(compositions) >= 2, compositions
    assert (tmp_path / "sweep" / "multirun.yaml").is_file()


def test_an_evaluation_of_no_run_is_refused_after_one_composition(tmp_path, compositions, cli_in_process):
    from hybrid_sysid.cli.evaluate import main

    code, _, err = cli_in_process(main, f"run={tmp_path / 'no_run'}", f"hydra.run.dir={tmp_path / 'ev'}", cwd=tmp_path)
    assert code == 2 and "run =" in err and ".hydra/config.yaml" in err, err
    assert len(compositions) == 1, compositions
    assert not (tmp_path / "ev").exists()


@pytest.mark.parametrize(
    "args",
    [["model.net.depth=3"], ["trainer.max_steps=abc"], ["objective=cross_segment", "objective.target.x=1"]],
)
def test_a_config_that_does_not_compose_is_refused_after_one_composition(
    tmp_path, compositions, cli_in_process, monkeypatch, args
):
    """An unknown key or a value of the wrong type fails the first composition as it fails the run's own: its line
    comes from the first, and says what Hydra's second composition made the command say (the reference: the same
    command with the early end turned off)."""
    from hybrid_sysid.cli.train import main
    from hybrid_sysid.launch import first_composition

    code, _, err = cli_in_process(main, *args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert len(compositions) == 1, compositions
    monkeypatch.setattr(first_composition, "fails_alike", lambda exc, overrides: False)
    compositions.clear()
    code_after_two, _, reference = cli_in_process(main, *args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert (code_after_two, reference) == (code, err) and len(compositions) == 2, (reference, compositions)
    assert not (tmp_path / "run").exists()


def test_a_value_list_without_m_is_left_to_the_runs_composition(tmp_path, compositions, cli_in_process):
    """seed=0,1 without -m: the first composition (for a sweep) takes the list, the run's refuses it before the unknown
    key; so the command says what Hydra says of the list, after two compositions."""
    from hybrid_sysid.cli.train import main

    code, _, err = cli_in_process(main, "seed=0,1", "model.net.depth=3", cwd=tmp_path)
    assert code == 2 and "Ambiguous value for argument 'seed=0,1'" in err, err
    assert len(compositions) == 2, compositions
