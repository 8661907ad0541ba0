"""The quarter-car physics in plain numpy (no numba, torch, Lightning or Hydra), usable from a notebook.

The compiled dataset kernels are ``hybrid_sysid.physics.compiled`` and ``compiled_sensors`` (the sensor faults of
``physics.sensors``), imported only by ``hybrid_sysid.data``; ``compiled_hardening``, the hardening fix's
recursion, and ``eiv.compiled_criterion``, a fault fix's criterion, are imported at such a fit's first call.
"""

from hybrid_sysid.core.options import DEFAULT_MEASUREMENT, MEASUREMENTS, ROAD_CLASSES, STEPPED
from hybrid_sysid.physics.exact import continuous_recordings, expm
from hybrid_sysid.physics.integrate import integrate, integrate_trapezoid, relative_states
from hybrid_sysid.physics.quarter_car import (
    Coefficients,
    QuarterCar,
    seat_car,
    simulate,
    stable_dt_limit,
    step,
)
from hybrid_sysid.physics.road import (
    road_amplitudes,
    road_phases,
    road_profiles,
    wave_amplitudes,
    wave_numbers,
)
from hybrid_sysid.physics.sensors import FaultDraws, SensorFaults, fractional_delay, lowpass

__all__ = [
    "DEFAULT_MEASUREMENT",
    "MEASUREMENTS",
    "ROAD_CLASSES",
    "Coefficients",
    "FaultDraws",
    "SensorFaults",
    "STEPPED",
    "QuarterCar",
    "continuous_recordings",
    "expm",
    "fractional_delay",
    "integrate",
    "integrate_trapezoid",
    "lowpass",
    "relative_states",
    "road_amplitudes",
    "road_phases",
    "road_profiles",
    "seat_car",
    "simulate",
    "stable_dt_limit",
    "step",
    "wave_amplitudes",
    "wave_numbers",
]
