"""A run trained on a range of noise says so wherever its settings are shown: the report's protocol line and the
trackers' hyperparameters (a single std would misdescribe experiment=anchored's networks)."""

from omegaconf import OmegaConf

from hybrid_sysid.report.protocol import _describe
from hybrid_sysid.training.tracking.hparams import hparams_values
from hybrid_sysid.training.tracking.naming import Naming

LABELLED = {"_target_": "hybrid_sysid.model.objectives.LabelledObjective"}


def test_the_protocol_and_the_hparams_give_the_training_noise_range():
    ranged = {"noise": {"train_std": 0.003, "train_std_max": 0.1, "eval_std": [0.0]}, "seed": 0, "objective": LABELLED}
    single = {"noise": {"train_std": 0.01, "train_std_max": None, "eval_std": [0.0]}, "seed": 0, "objective": LABELLED}
    assert _describe(ranged, {})["training noise std"] == "0.003-0.1 (log-uniform per training window)"
    assert _describe(single, {})["training noise std"] == "0.01"
    values = hparams_values(OmegaConf.create(ranged), Naming())
    assert values["noise.train_std"] == 0.003 and values["noise.train_std_max"] == 0.1
    assert "noise.train_std_max" not in hparams_values(OmegaConf.create(single), Naming())
