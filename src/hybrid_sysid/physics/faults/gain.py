"""Each accelerometer's calibration gain: its output is its true acceleration times its own gain (docs/faults.md)."""

from __future__ import annotations

from hybrid_sysid.physics.faults.base import Fault, Setting, value_of


class Gain(Fault):
    name = "gain"
    settings = (
        Setting(
            "gain_spread",
            0.0,
            "each sensor's calibration gain (sensitivity) error",
            unit="fraction",
            drawn="each sensor's gain uniform in [1 - s, 1 + s]",
            preset="`sensor=gain`: 0.03",
            high=1.0,
            high_open=True,
            allowed="gains in [1 - s, 1 + s]",
            keyed_at_default=True,
        ),
    )
    fix = "gain"  # the ratio of the two gains fitted with p (baselines.fixes.fit_gain, physics.eiv "gain")
    fix_rank = 30
    order = 20
    compiled = True

    def draw(self, config, n, rng):
        """(n, 2) gains, seat then body; exactly 1 when off."""
        return 1.0 + value_of(config, self.settings[0]) * rng.uniform(-1.0, 1.0, size=(n, 2))

    def apply(self, seat, body, draw, dt, **context):
        return draw[:, :1] * seat, draw[:, 1:] * body
