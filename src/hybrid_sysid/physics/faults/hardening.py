"""A model mismatch: a hardening seat spring, F = K3 (d + kappa d^3), d the seat-minus-body displacement.

Not a sensor fault: a constant of the car (``car.seat_hardening``, a QuarterCar field), which the simulation's step
carries (physics.quarter_car.step, physics.compiled), so nothing is drawn and nothing acts on the recorded signals.
p2 = K3 / m3 stays the label, the small-amplitude stiffness (docs/faults.md, "Hardening seat spring").
"""

from __future__ import annotations

from hybrid_sysid.core.checks import bad
from hybrid_sysid.core.options import STEPPED
from hybrid_sysid.physics.faults.base import Fault, Setting, value_of

# kappa above this: at d = 1 cm the cubic force is 1000 times the linear one, and a class E road's motion then
# overflows the semi-implicit step into NaN (the step's stability is that of the linearised car)
HARDENING_MAX = 1e7
HARDENING_UNIT = "1/m^2; 35000 in car=hardening_seat"


class Hardening(Fault):
    name = "hardening"
    settings = (
        Setting(
            "seat_hardening",
            0.0,
            "a hardening seat spring, F = K3 (d + kappa d^3)",
            unit="1/m^2",
            drawn="nothing: a car constant",
            preset="`car=hardening_seat`: 35000",
            high=HARDENING_MAX,
            allowed=HARDENING_UNIT,
            section="car",
        ),
    )
    fix = "hardening"  # the cube of the displacement a third regressor (baselines.fixes, physics.eiv "hardening")
    fix_rank = 10
    compiled = True  # the step itself, numpy's and the kernel's

    def validate(self, config, dt, window=None, measurement=None):
        super().validate(config, dt, window, measurement)
        kappa = value_of(config, self.settings[0])
        if kappa and measurement is not None and measurement not in STEPPED:
            bad(
                "car.seat_hardening",
                kappa,
                "0 with data.measurement = continuous: its exact solution is of the linear car (physics.exact)",
            )
