"""estimator= sets the network and its objective (or a baseline), conf/estimator; a model=, objective= or
baseline= beside it would win in Hydra and train something else under the estimator's name. The reference is the
estimator's own config file: what it overrides is what may not be given beside it."""

from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.launch.choices import SET_BY_ESTIMATOR, check_choices, check_estimator


def overridden_groups(name):
    """The groups conf/estimator/<name>.yaml overrides in its defaults list."""
    defaults = yaml.safe_load((Path(CONF_DIR) / "estimator" / f"{name}.yaml").read_text())["defaults"]
    return {next(iter(d)).split()[-1].lstrip("/") for d in defaults if isinstance(d, dict)}


def test_the_groups_refused_beside_an_estimator_are_those_estimators_set():
    names = [p.stem for p in Path(CONF_DIR, "estimator").glob("*.yaml")]
    assert len(names) >= 8
    assert set().union(*map(overridden_groups, names)) == set(SET_BY_ESTIMATOR)


@pytest.mark.parametrize("extra", [["model=paper_cnn"], ["objective=hybrid"], ["baseline=ls_window"]])
def test_a_run_naming_an_estimator_and_a_group_it_sets_is_one_line_and_makes_nothing(
    extra, tmp_path, cli_in_process, tiny_cache
):
    from hybrid_sysid.cli.train import main

    run = tmp_path / "run"
    args = ["estimator=anchored_label_free", *extra, "data=tiny", "trainer=debug", f"hydra.run.dir={run}"]
    code, _, err = cli_in_process(main, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert (
        err.startswith("error: estimator = 'anchored_label_free' is not allowed") and extra[0][:-1].split("=")[0] in err
    )
    assert not run.exists() and not (tmp_path / "outputs").exists()


def test_a_sweep_of_estimators_beside_an_objective_is_one_line_before_its_directory(
    tmp_path, cli_in_process, tiny_cache
):
    from hybrid_sysid.cli.train import main

    sw = tmp_path / "sw"
    args = [
        "-m",
        "estimator=ls,cnn_labelled",
        "objective=hybrid",
        "data=tiny",
        "trainer=debug",
        f"hydra.sweep.dir={sw}",
    ]
    code, _, err = cli_in_process(main, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 2 and "estimator = 'ls,cnn_labelled' is not allowed: beside objective=" in err, err[-2000:]
    assert not sw.exists()


def composed(*overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides), return_hydra_config=True)


@pytest.mark.parametrize(
    "overrides, refused",
    [
        (["experiment=anchored"], False),  # sweeps estimator= alone
        (["experiment=anchored", "objective=hybrid"], True),
        (["experiment=robustness"], False),  # sweeps objective= without an estimator
        (["experiment=robustness", "estimator=ls"], True),
        (["estimator=cnn_labelled", "model.optim.lr=0.01", "objective.p_scale=[1,1]"], False),  # values, not choices
    ],
)
def test_presets_and_values_under_the_groups_pass(overrides, refused):
    cfg = composed(*overrides)
    if refused:
        with pytest.raises(ConfigError):
            check_estimator(cfg)
    else:
        check_estimator(cfg)


# A baseline has no network: the groups it never reads are those only the network estimators set (conf/estimator).
NETWORK_GROUPS = {"model", "objective"}


def test_the_groups_refused_beside_a_baseline_are_those_only_networks_set():
    from hybrid_sysid.launch.choices import UNREAD_BY_BASELINE

    names = [p.stem for p in Path(CONF_DIR, "estimator").glob("*.yaml")]
    networks = [n for n in names if "baseline" not in overridden_groups(n)]
    baselines = [n for n in names if "baseline" in overridden_groups(n)]
    assert networks and baselines
    assert set().union(*map(overridden_groups, networks)) == NETWORK_GROUPS == set(UNREAD_BY_BASELINE)
    assert set().union(*map(overridden_groups, baselines)) == {"baseline"}


@pytest.mark.parametrize(
    "args, key",
    [
        (["baseline=eiv", "objective=hybrid"], "objective"),
        (["baseline=ls_window", "model=paper_cnn"], "model"),
        (["-m", "baseline=eiv,ls_window", "objective=hybrid,labelled"], "objective"),
        (["-m", "experiment=robustness", "baseline=ls_window"], "objective"),  # the preset sweeps objective=
        (["-m", "experiment=baselines", "objective=hybrid"], "objective"),  # the preset sweeps baseline=
    ],
)
def test_a_model_or_objective_beside_a_baseline_is_one_line_naming_it_and_makes_nothing(
    args, key, tmp_path, cli_in_process, tiny_cache
):
    """P22 (docs/reliability/adversarial_physical_limit.md): the record named an objective no baseline reads."""
    from hybrid_sysid.cli.train import main

    out = tmp_path / "out"
    where = f"hydra.sweep.dir={out}" if "-m" in args else f"hydra.run.dir={out}"
    code, _, err = cli_in_process(
        main, *args, "data=tiny", "trainer=debug", where, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache}
    )
    assert code == 2 and len(err.strip().splitlines()) == 1, err[-2000:]
    assert err.startswith(f"error: {key} = ") and "beside baseline=" in err, err
    assert not out.exists() and not (tmp_path / "outputs").exists()


@pytest.mark.parametrize(
    "overrides",
    [
        ["baseline=eiv"],
        ["~baseline", "objective=hybrid", "model=paper_cnn"],  # no baseline: both are read
        ["baseline=ls_bandpass", "model.optim.lr=0.01"],  # a value, not a choice
        ["baseline=eiv", "~objective"],  # a deletion chooses nothing
    ],
)
def test_a_baseline_alone_or_with_values_passes(overrides):
    check_choices(composed(*overrides))


def test_every_preset_and_estimator_passes_the_choices_check():
    """Each experiment (with and without debug=fast) and each estimator, as shipped, composes to allowed choices."""
    experiments = sorted(p.stem for p in Path(CONF_DIR, "experiment").glob("*.yaml"))
    estimators = sorted(p.stem for p in Path(CONF_DIR, "estimator").glob("*.yaml"))
    assert "anchored_clean" in experiments and "eiv" in estimators
    for overrides in (
        *([f"experiment={e}"] for e in experiments),
        *([f"experiment={e}", "debug=fast"] for e in experiments),
        *([f"estimator={e}"] for e in estimators),
    ):
        check_choices(composed(*overrides))
