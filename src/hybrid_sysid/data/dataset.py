"""Dataset generation (sec. 2.3): every mass on every road, simulated into float32 channels.

Recordings are stored road-major (recording = road * n_masses + mass index): a split by road (data.splits) takes
whole roads, so no test road is ever seen in training. The on-disk cache is
hybrid_sysid.data.cache.

With sensor faults (``data.sensor``, physics.sensors) the recorded channels are those of the faulty sensors, and
rel_vel and rel_disp are re-integrated from them, as a user would from such a recording; the labels stay the
true p. Each recording draws its faults from a generator of its own, seeded [data.seed, FAULT_STREAM], so the
clean draws (classes, masses, roads, seat constants) are those of the same dataset without faults.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybrid_sysid.data.spec import CHANNELS, DatasetSpec
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
from hybrid_sysid.physics.compiled_sensors import apply_faults, simulate_faulted
from hybrid_sysid.physics.faults import FaultDraws, apply, fault
from hybrid_sysid.physics.faults.skew import DELAY_HALF_WIDTH

ARRAYS = CHANNELS + ("params", "m3", "c3", "k3", "road_id", "road_class")  # what a dataset holds, and the cache
FAULT_STREAM = 0x5E2503  # the second word of the fault draws' seed, [data.seed, FAULT_STREAM]


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


def fault_draws(spec: DatasetSpec) -> FaultDraws:
    """Every recording's sensor faults (gains, skews in seconds, cut-offs in Hz), as generate_dataset draws them."""
    n = spec.n_roads * spec.n_masses
    return spec.sensor.draw(n, np.random.default_rng([spec.seed, FAULT_STREAM]))


def skew_margin(spec: DatasetSpec) -> int:
    """Steps simulated past a recording's end, and rest (zeros) put before its start, for the faults to read (the
    skew's delay): then every sample of the recording is made from true samples, none from an edge's extension."""
    return spec.sensor.margin(spec.dt)


def generate_dataset(spec: DatasetSpec) -> SimulatedDataset:
    """Simulate every mass on every road.

    The compiled kernel (physics.compiled) steps the simulation in float64 and writes the float32 channels
    directly: the same numbers as ``simulate`` and ``relative_states`` cast to float32. With sensor faults, the
    float64 channels go through ``physics.sensors.apply`` and are re-integrated before the cast, block by block
    inside the kernel (physics.compiled_sensors).
    """
    spec.validate()
    rng = np.random.default_rng(spec.seed)
    classes = spec.road_class(rng)
    masses = rng.integers(spec.m3_min, spec.m3_max + 1, size=(spec.n_roads, spec.n_masses)).astype(float).ravel()
    road_id = np.repeat(np.arange(spec.n_roads), spec.n_masses)
    margin = skew_margin(spec)
    if spec.measurement in STEPPED:  # a longer road starts as the same road: the phases do not depend on its length
        roads = road_profiles(classes, spec.n_steps + margin, spec.dt, spec.speed, spec.n_waves, rng)
    else:  # the same draw of phases; the road stays analytic
        phases = road_phases(spec.n_roads, spec.n_waves, rng)
    c3, k3 = np.full(len(masses), spec.car.c3), np.full(len(masses), spec.car.k3)
    if spec.seat_spread:  # drawn after the roads, so a spread of 0 leaves the paper's data as they were
        s = spec.seat_spread
        c3 = spec.car.c3 * rng.uniform(1 - s, 1 + s, size=len(masses))
        k3 = spec.car.k3 * rng.uniform(1 - s, 1 + s, size=len(masses))

    # float64 physics ends here: the network and the objectives work in float32
    draws = fault_draws(spec) if spec.sensor.active else None
    arguments = (roads, road_id, masses, spec.dt, spec.car, spec.measurement) if spec.measurement in STEPPED else ()
    if arguments and draws is None:
        channels = simulate_recordings(*arguments, c3=c3, k3=k3)
    elif arguments and compiled(draws):
        channels = simulate_faulted(*arguments, draws, spec.n_steps, margin, DELAY_HALF_WIDTH, c3=c3, k3=k3)
    else:  # the numpy path: the exact solution, or a fault the kernel does not apply
        if arguments:
            clean = tuple(np.empty((len(masses), roads.shape[1])) for _ in range(4))
            seat, body = simulate_recordings(*arguments, out=clean, c3=c3, k3=k3)[:2]
        else:
            seat, body = continuous_recordings(
                road_amplitudes(classes, spec.n_waves),
                phases,
                wave_numbers(spec.n_waves) * spec.speed,
                road_id,
                masses,
                spec.n_steps + margin,
                spec.dt,
                spec.car,
                c3=c3,
                k3=k3,
            )
        if draws is not None:
            seat, body = faulted(seat, body, draws, spec.dt, margin, spec.n_steps)
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


def compiled(draws: FaultDraws) -> bool:
    """Whether the compiled kernel applies every fault drawn (physics.compiled_sensors)."""
    return all(fault(name).compiled for name, draw in draws.items() if draw is not None)


def faulted(seat: np.ndarray, body: np.ndarray, draws: FaultDraws, dt: float, margin: int, n_steps: int):
    """The faulty sensors' (seat, body), float64 (n, n_steps), of clean channels simulated ``margin`` steps past
    n_steps: preceded by ``margin`` samples of rest (the car stands still before t0), faulted, cropped to the
    recording. What ``simulate_faulted`` does inside its kernel."""
    if margin:
        seat, body = (np.pad(x, ((0, 0), (margin, 0))) for x in (seat, body))
    seat, body = (apply_faults if compiled(draws) else apply)(seat, body, draws, dt, DELAY_HALF_WIDTH)
    return seat[:, margin : margin + n_steps], body[:, margin : margin + n_steps]
