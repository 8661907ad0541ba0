"""Recording faults of the two accelerometers (docs/faults.md): calibration gain, time skew, anti-alias low-pass.

Each fault is its own file of ``physics.faults`` (the settings, the draw, how it acts, its fix); this module keeps
the names other modules and notebooks import: ``SensorFaults`` holds the magnitudes (the ``sensor.*`` config keys),
``FaultDraws`` each recording's draws, ``apply`` puts them on the clean signals, and the filters they use. Plain
numpy; the dataset runs the same arithmetic compiled (physics.compiled_sensors, tested equal).
"""

from hybrid_sysid.physics.faults.chain import FaultDraws, SensorFaults, apply
from hybrid_sysid.physics.faults.lowpass import butterworth, lowpass
from hybrid_sysid.physics.faults.skew import BETA_MAX, BETA_PER_TAP, delay_taps, fractional_delay

__all__ = [
    "BETA_MAX",
    "BETA_PER_TAP",
    "FaultDraws",
    "SensorFaults",
    "apply",
    "butterworth",
    "delay_taps",
    "fractional_delay",
    "lowpass",
]
