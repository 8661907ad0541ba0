"""The estimator and fault groups (conf/estimator, conf/fault) that experiment=anchored sweeps: each preset
selects what its name says, and ls_fix picks the classical fix of the fault the config simulates."""

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from hybrid_sysid.config import CONF_DIR

ESTIMATORS = sorted(p.stem for p in (Path(CONF_DIR) / "estimator").glob("*.yaml"))
FAULTS = sorted(p.stem for p in (Path(CONF_DIR) / "fault").glob("*.yaml"))


def composed(*overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


@pytest.mark.parametrize("name", ESTIMATORS)
def test_an_estimator_preset_selects_its_model_and_objective_or_a_baseline(name):
    choices = composed(f"estimator={name}")
    if name.startswith("ls"):
        assert choices.baseline.span == "window" and choices.baseline.filter == "bandpass"
        return
    if name.startswith("eiv"):  # the errors-in-variables fit of each window, with the simulator's prior for _map
        bayes = name == "eiv_bayes"  # the Bayes estimate under the simulator's exact prior
        assert choices.baseline._target_.endswith("ErrorsInVariablesBayes" if bayes else "ErrorsInVariablesFit")
        assert (choices.baseline.prior is not None) == ("_map" in name or bayes)
        return
    model, objective = name.split("_", 1)
    # a preset named for a network option: its model, its objective and the option it sets
    objective, option = {"partner": ("cross_segment", "partner")}.get(objective, (objective, None))
    if option is not None:
        assert choices.model.net[option] is True and composed(f"model={model}").model.net[option] is False
    assert choices.baseline is None
    assert choices.model.net._target_.endswith({"cnn": "FastCNN", "anchored": "AnchoredCNN"}[model])
    assert OmegaConf.to_container(choices.objective) == OmegaConf.to_container(
        composed(f"objective={objective}").objective
    )


@pytest.mark.parametrize(
    "fault, fix",
    [("clean", "none"), ("gain", "gain"), ("skewed", "skew"), ("lowpass", "skew"), ("hardening", "hardening")],
)
def test_ls_fix_fits_the_fault_the_config_simulates(fault, fix):
    assert fault in FAULTS
    cfg = composed("estimator=ls_fix", f"fault={fault}")
    assert cfg.baseline.fix == fix
