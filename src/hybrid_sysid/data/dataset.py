"""Dataset generation (sec. 2.3): every mass on every road, simulated into float32 channels.

Recordings are stored road-major (recording = road * n_masses + mass index): a split by road (data.splits) takes
whole roads, so no test road is ever seen in training. The on-disk cache is
hybrid_sysid.data.cache.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybrid_sysid.data.spec import DatasetSpec
from hybrid_sysid.physics import (
    STEPPED,
    continuous_recordings,
    relative_states,
    road_amplitudes,
    road_phases,
    road_profiles,
    wave_numbers,
)
from hybrid_sysid.physics.compiled import simulate_recordings

CHANNELS = ("seat_acc", "body_acc", "rel_vel", "rel_disp")
ARRAYS = CHANNELS + ("params", "m3", "c3", "k3", "road_id", "road_class")  # what a dataset holds, and the cache


@dataclass
class SimulatedDataset:
    """Arrays of one simulated dataset. Channels are float32 (n_recordings, n_steps); labels float64."""

    spec: DatasetSpec
    seat_acc: np.ndarray
    body_acc: np.ndarray
    rel_vel: np.ndarray
    rel_disp: np.ndarray
    params: np.ndarray  # (n, 2): p1 = C3 / m3, p2 = K3 / m3
    m3: np.ndarray  # (n,)
    c3: np.ndarray  # (n,) the seat's damping and stiffness of each recording (the car's unless data.seat_spread)
    k3: np.ndarray  # (n,)
    road_id: np.ndarray  # (n,)
    road_class: np.ndarray  # (n,) class letters

    def __len__(self) -> int:
        return self.seat_acc.shape[0]

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, n).nbytes for n in ARRAYS)


def generate_dataset(spec: DatasetSpec) -> SimulatedDataset:
    """Simulate every mass on every road.

    The compiled kernel (physics.compiled) steps the simulation in float64 and writes the float32 channels
    directly: the same numbers as ``simulate`` and ``relative_states`` cast to float32.
    """
    spec.validate()
    rng = np.random.default_rng(spec.seed)
    classes = spec.road_class(rng)
    masses = rng.integers(spec.m3_min, spec.m3_max + 1, size=(spec.n_roads, spec.n_masses)).astype(float).ravel()
    road_id = np.repeat(np.arange(spec.n_roads), spec.n_masses)
    if spec.measurement in STEPPED:
        roads = road_profiles(classes, spec.n_steps, spec.dt, spec.speed, spec.n_waves, rng)
    else:  # the same draw of phases; the road stays analytic
        phases = road_phases(spec.n_roads, spec.n_waves, rng)
    c3, k3 = np.full(len(masses), spec.car.c3), np.full(len(masses), spec.car.k3)
    if spec.seat_spread:  # drawn after the roads, so a spread of 0 leaves the paper's data as they were
        s = spec.seat_spread
        c3 = spec.car.c3 * rng.uniform(1 - s, 1 + s, size=len(masses))
        k3 = spec.car.k3 * rng.uniform(1 - s, 1 + s, size=len(masses))

    # float64 physics ends here: the network and the objectives work in float32
    if spec.measurement in STEPPED:
        channels = simulate_recordings(roads, road_id, masses, spec.dt, spec.car, spec.measurement, c3=c3, k3=k3)
    else:
        seat, body = continuous_recordings(
            road_amplitudes(classes, spec.n_waves),
            phases,
            wave_numbers(spec.n_waves) * spec.speed,
            road_id,
            masses,
            spec.n_steps,
            spec.dt,
            spec.car,
            c3=c3,
            k3=k3,
        )
        rel = relative_states(seat, body, spec.dt, spec.measurement)
        channels = tuple(x.astype(np.float32) for x in (seat, body, *rel))
    return SimulatedDataset(
        spec=spec,
        params=np.stack([c3 / masses, k3 / masses], axis=1),
        m3=masses,
        c3=c3,
        k3=k3,
        road_id=road_id,
        road_class=np.repeat(classes, spec.n_masses),
        **dict(zip(CHANNELS, channels)),
    )
