"""Consistent-measurement recordings simulated with the physics layer, cut into the data module's batch dict."""

import numpy as np
import pytest
import torch

from hybrid_sysid.physics import QuarterCar, relative_states, road_profiles, simulate


def make_batch(classes, masses, dt=0.005, n_steps=800, start=300, window=500, seed=0):
    """One recording per (class, mass) pair; rel states integrated over the whole recording, then cropped."""
    road = road_profiles(classes, n_steps, dt, speed=15.0, rng=seed)
    masses = np.asarray(masses, dtype=float)
    seat, body = simulate(road, masses, dt, measurement="consistent")
    rel_vel, rel_disp = relative_states(seat, body, dt, "consistent")
    win = slice(start, start + window)
    f32 = lambda a: torch.tensor(a, dtype=torch.float32)  # noqa: E731 -- float64 physics -> float32 network
    return {
        "signals": f32(np.stack([seat[:, win], body[:, win]], axis=1)),
        "params": f32(np.stack(QuarterCar().parameters(masses), axis=-1)),
        "rel_vel": f32(rel_vel[:, win]),
        "rel_disp": f32(rel_disp[:, win]),
    }


@pytest.fixture(scope="module")
def consistent_batch():
    """Six recordings: smooth, medium and rough roads, light to heavy seats."""
    return make_batch(list("AACCEE"), [50, 200, 80, 170, 120, 140])


@pytest.fixture(scope="module")
def batch_factory():
    return make_batch
