"""The quarter-car physics in plain numpy (no numba, torch, Lightning or Hydra), usable from a notebook.

The compiled dataset kernel is ``hybrid_sysid.physics.compiled``, imported only by ``hybrid_sysid.data``.
"""

from hybrid_sysid.physics.integrate import integrate, relative_states
from hybrid_sysid.physics.quarter_car import (
    DEFAULT_MEASUREMENT,
    MEASUREMENTS,
    Coefficients,
    QuarterCar,
    simulate,
    stable_dt_limit,
    step,
)
from hybrid_sysid.physics.road import ROAD_CLASSES, road_profiles, wave_amplitudes, wave_numbers

__all__ = [
    "DEFAULT_MEASUREMENT",
    "MEASUREMENTS",
    "ROAD_CLASSES",
    "Coefficients",
    "QuarterCar",
    "integrate",
    "relative_states",
    "road_profiles",
    "simulate",
    "stable_dt_limit",
    "step",
    "wave_amplitudes",
    "wave_numbers",
]
