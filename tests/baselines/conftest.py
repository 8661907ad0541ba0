"""Clean consistent-measurement recordings in float64, straight from the physics layer (no data module)."""

import numpy as np
import pytest

from hybrid_sysid.physics import QuarterCar, relative_states, road_profiles, simulate


@pytest.fixture(scope="module")
def clean_recordings():
    """Six recordings of 1200 steps at 5 ms (smooth to rough roads, light to heavy seats), float64:
    seat, body, rel_vel, rel_disp (integrated from t0) and the true (p1, p2)."""
    dt, masses = 0.005, np.array([50.0, 200.0, 80.0, 170.0, 120.0, 140.0])
    road = road_profiles(list("AACCEE"), 1200, dt, speed=15.0, rng=3)
    seat, body = simulate(road, masses, dt, measurement="consistent")
    rel_vel, rel_disp = relative_states(seat, body, dt, "consistent")
    p = np.stack(QuarterCar().parameters(masses), axis=-1)
    return {"dt": dt, "seat": seat, "body": body, "rel_vel": rel_vel, "rel_disp": rel_disp, "p": p}


@pytest.fixture(scope="package")
def compose_cfg(tmp_path_factory):
    """The app's config composed from overrides, with one dataset cache for this folder's tests (each dataset of
    data=tiny simulated once) and no progress bar."""
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR

    cache = tmp_path_factory.mktemp("cache")

    def _make(*overrides):
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            return compose(
                config_name="config", overrides=[*overrides, f"data.cache_dir={cache}", "trainer.progress_bar=false"]
            )

    return _make
