"""data.serving: the window, batch and noise arguments both built-in data modules take, each default written once
(by WindowSettings, BatchSettings or Serving) and each range checked by its owner, whichever module is built."""

import inspect

import numpy as np
import pytest
from omegaconf import OmegaConf

from hybrid_sysid.config.targets import build
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec, WindowSettings
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.data.recordings import RecordingsDataModule
from hybrid_sysid.data.recordings_files import index, split_recordings
from hybrid_sysid.data.serving import Serving
from hybrid_sysid.data.spec import BatchSettings

from helpers.recordings import seat_recordings, write_folder

SPEC = DatasetSpec(n_roads=6, n_masses=5, n_steps=400, seed=1)
SERVED = ["window", "batch_size", "eval_batch_size", "train_std", "seed", "integration", "fir", "train_std_max"]
SERVED += ["outside_fir", "outside_target", "outside_fix"]


@pytest.fixture
def recordings(tmp_path):
    """A RecordingsDataModule over six short recordings, given only the module's own arguments."""
    seat, body, *_ = seat_recordings(6, 240, 0.005, seed=2)
    write_folder(tmp_path, seat, body, 0.005)
    idx = index(tmp_path)

    def make(**serving):
        split = split_recordings(len(idx.recordings), 0.8, 0.125, seed=0)
        return RecordingsDataModule(idx, split, "continuous", lambda s, b, dt, m: np.zeros((len(s), 2)), **serving)

    return make


@pytest.mark.parametrize("cls", [QuarterCarDataModule, RecordingsDataModule])
def test_both_modules_take_the_served_arguments_by_name_with_their_owners_defaults(cls):
    params = inspect.signature(cls).parameters
    served = [n for n, p in params.items() if p.kind is p.KEYWORD_ONLY and n in SERVED]
    assert served == SERVED and not any(p.kind is p.VAR_KEYWORD for p in params.values())
    window, batches = WindowSettings(), BatchSettings()  # the owners, built with their own defaults
    assert params["window"].default == window.window and params["integration"].default == window.integration
    assert params["batch_size"].default == batches.batch_size and params["train_std"].default == batches.train_std
    assert params["train_std_max"].default is batches.train_std_max
    if cls is QuarterCarDataModule:
        assert params["train_fraction"].default == window.train_fraction
        assert params["val_fraction"].default == window.val_fraction


def test_a_module_built_with_no_served_argument_holds_the_owners_defaults(recordings):
    batches, served = BatchSettings(), Serving()
    for dm in (QuarterCarDataModule(SPEC, window=100), recordings(window=100)):
        assert (dm.batch_size, dm.train_std, dm.train_std_max) == (batches.batch_size, batches.train_std, None)
        assert (dm.eval_batch_size, dm.seed) == (served.eval_batch_size, served.seed)
        assert dm.integration == WindowSettings().integration
        assert dm.fir is None and dm.outside_fir is None and dm.outside_target is None


def test_the_served_values_reach_the_module_as_given(recordings):
    fir = np.ones(5) / 5
    given = dict(window=120, batch_size=7, eval_batch_size=9, train_std=0.01, seed=5, integration="window", fir=fir)
    given |= dict(train_std_max=0.1, outside_target="eiv")
    for dm in (QuarterCarDataModule(SPEC, **given), recordings(**given)):
        assert {k: getattr(dm, k) for k in given} == given
        assert isinstance(dm.train_std, float) and isinstance(dm.train_std_max, float)


@pytest.mark.parametrize(
    "serving",
    [dict(batch_size=0), dict(train_std=-0.01), dict(train_std=2000.0), dict(train_std_max=0.1)],
    ids=["batch_size", "negative", "huge", "max without std"],
)
def test_both_modules_refuse_bad_batches_with_the_owners_line(recordings, serving):
    with pytest.raises(ConfigError) as owner:
        BatchSettings(**serving).validate()
    for make in (lambda: QuarterCarDataModule(SPEC, window=100, **serving), lambda: recordings(window=100, **serving)):
        with pytest.raises(ConfigError) as exc:
            make()
        assert str(exc.value) == str(owner.value) and "\n" not in str(exc.value)


def test_positional_arguments_past_cache_dir_are_refused_not_taken_as_train_fraction():
    with pytest.raises(TypeError, match="positional"):
        QuarterCarDataModule(SPEC, None, 100)
    with pytest.raises(TypeError, match="'windw'"):
        QuarterCarDataModule(SPEC, windw=100)


@pytest.mark.parametrize("cls", [QuarterCarDataModule, RecordingsDataModule])
def test_a_misspelt_data_module_argument_names_its_key_and_every_argument(cls):
    node = OmegaConf.create({"_target_": f"{cls.__module__}.{cls.__name__}", "windw": 3})
    with pytest.raises(ConfigError) as exc:
        build(node, "data.module")
    message = str(exc.value)
    assert message.startswith(f"data.module.windw = 3 is not allowed: not an argument of {cls.__name__}")
    assert message.endswith(", ".join(SERVED))
