"""A constant offset per sensor, declared outside hybrid_sysid: docs/faults.md's example of adding a fault."""

from hybrid_sysid.physics.faults import Fault, Setting, value_of


class Offset(Fault):
    """Each accelerometer reads its true acceleration plus a constant offset (a zero error), drawn per recording."""

    name = "offset"
    settings = (
        Setting(
            "offset_std",  # the config key sensor.offset_std; its default, 0, turns the fault off
            0.0,
            "each sensor's constant offset (zero error)",
            unit="m/s^2",
            drawn="each sensor's offset normal, std offset_std",
            preset="`fault=offset`: 0.01",
            high=1.0,  # checked as [0, 1]: the road's accelerations are a few m/s^2
            allowed="m/s^2, the offsets' std",
        ),
    )
    fix = "none"  # the band-passed fit removes a constant already: no parameter to add
    order = 25  # after the gain (the electronics' zero), before the skew

    def draw(self, config, n, rng):
        unit = rng.standard_normal((n, 2))  # drawn always, so the faults registered after keep their draws
        std = value_of(config, self.settings[0])
        return std * unit if std else None  # None: nothing to apply

    def apply(self, seat, body, draw, dt, **context):
        return seat + draw[:, :1], body + draw[:, 1:]
