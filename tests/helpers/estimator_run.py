"""The trained run that test_estimator.py and test_predict.py share (fixtures tiny_run and est in conftest.py), and
recordings simulated like its data."""

import numpy as np
import pytest
from omegaconf import OmegaConf

from hybrid_sysid.physics import road_profiles, simulate

from helpers.shared import built_once

TINY = [
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=400",
    "trainer.eval_every_n_steps=100",
    "trainer.progress_bar=false",
]
C3, K3 = 615.0, 98935.0  # the paper's seat damper and spring (sec. 2.2)


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory, tiny_cache):
    """A FastCNN trained for 400 steps on data=tiny, its config saved as Hydra would. About 8% mean relative
    deviation on recordings simulated like its data, against 32% for a constant guess (200 steps: 18%, too close
    to half of it): enough to tell right input from wrong. Trained once per test run, by one worker under
    pytest -n (its data from the shared cache, conftest.py's tiny_cache); a test that changes it works on a copy."""
    overrides = [*TINY, f"data.cache_dir={tiny_cache}"]
    return built_once(tmp_path_factory, "tiny_estimator_run", lambda run_dir: trained_run(run_dir, overrides))


def trained_run(run_dir, overrides):
    """A run trained in this process from the config ``overrides`` compose, saved as Hydra would save it."""
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.training.run import train

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
    train(cfg, run_dir, overrides)
    (run_dir / ".hydra").mkdir(exist_ok=True)
    OmegaConf.save(cfg, run_dir / ".hydra" / "config.yaml")
    return run_dir


@pytest.fixture(scope="session")
def est(tiny_run):
    from hybrid_sysid import load_estimator

    return load_estimator(tiny_run)


def recordings(n, n_steps, dt, seed=7, speed=15.0):
    """n recordings simulated like the run's data (consistent measurement): seat, body (n, n_steps), true p."""
    m3 = np.random.default_rng(seed).uniform(50, 200, n)
    road = road_profiles(("ABCDE" * n)[:n], n_steps, dt, speed, rng=seed)
    seat, body = simulate(road, m3, dt, measurement="consistent")
    return seat, body, np.stack([C3 / m3, K3 / m3], axis=1)


def predict(capsys, *argv):
    """hybrid-sysid-predict's main(argv) in process: (exit status, stdout, stderr)."""
    from hybrid_sysid.cli.predict import main

    try:
        main(list(argv))
        code = 0
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err
