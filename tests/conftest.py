import os

import pytest
from hydra import compose, initialize_config_dir

pytest_plugins = ["estimator_run"]  # the trained run test_estimator.py and test_predict.py share (tiny_run, est)


@pytest.fixture
def make_cfg(tmp_path):
    """Compose the app's config with overrides; the dataset cache goes to a per-test folder."""
    from hybrid_sysid.config import CONF_DIR  # here, so tests that need no torch start fast

    def _make(*overrides):
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            return compose(
                config_name="config",
                overrides=[f"data.cache_dir={tmp_path / 'cache'}", "trainer.progress_bar=false", *overrides],
            )

    return _make


@pytest.fixture
def poison_labels(monkeypatch):
    """A call that replaces every label of the datasets loaded afterwards by garbage: a label-free run, its
    model selection and its search must not notice."""

    def _poison():
        import numpy as np

        import hybrid_sysid.data.datamodule as dm_module

        real = dm_module.get_dataset

        def poisoned(spec, cache_dir=None):
            ds = real(spec, cache_dir)
            ds.params = np.random.default_rng(1).uniform(1.0, 5000.0, ds.params.shape)
            return ds

        monkeypatch.setattr(dm_module, "get_dataset", poisoned)

    return _poison


@pytest.fixture(autouse=True)
def _two_threads():
    import torch

    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)  # the basic launcher and tests share one process: restore global state


os.environ.setdefault("HYDRA_FULL_ERROR", "1")
