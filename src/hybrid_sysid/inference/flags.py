"""When not to trust an estimate: the flags ``Estimator.predict`` adds to its table (docs/predict.md, "Flags").

range     a network's estimate beyond the range of p the run was trained on (its data spec: (C3, K3) (1 -/+ s) /
          [m3_max, m3_min]) or within EDGE of its edge, in p1 or p2 (EDGE: a fraction of the range's width in log
          p, the same in log m3), or within BOUND_RTOL of the network's output bound: a seat mass outside the
          trained range comes out at or near the range's edge, not where it is. A least-squares baseline does not
          saturate: its estimate is flagged only more than RANGE_RTOL outside the range, where it was never tested.
channels  the recording's channel powers unlike those of recordings simulated from the run's own data spec: the
          seat-to-body power ratio around the seat resonance (the seat amplifies the body's motion there, so
          swapped channels invert it) beyond their range by more than a factor RATIO_FACTOR in power, or the
          body acceleration's power (a common scale: other units) by more than LEVEL_FACTOR.
run_error the run's own clean test error (metrics.json) above RUN_ERROR_LIMIT, or unknown.

Plain numpy on the run's config and record; the reference recordings come from the package's own data code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from omegaconf import DictConfig

from hybrid_sysid.config.resolvers import p_prior
from hybrid_sysid.core.words import count
from hybrid_sysid.data.dataset import generate_dataset
from hybrid_sysid.data.spec import DatasetSpec, window_starts
from hybrid_sysid.physics import QuarterCar

RANGE, CHANNELS, RUN_ERROR = "range", "channels", "run_error"
BOUND_RTOL = 0.02  # an estimate within 2% of a network's output bound counts as saturated
# a network's estimate within EDGE of the trained range's edge (a fraction of the range's width in log p) may be a
# seat mass beyond it read at the edge; 0.02 flags 3-5% of in-range test recordings (benchmarks/range_flag.py)
EDGE = 0.02
RANGE_RTOL = 0.02  # a baseline's fit more than 2% beyond the trained range is outside it (an exact fit is not)
RUN_ERROR_LIMIT = 0.10  # clean test mean relative deviation (either parameter) above which every estimate is flagged
# how far (a factor in power) a recording's seat-to-body power ratio and body power may lie beyond the range of the
# simulated reference recordings: the ratio is a property of the car (road class and realisation change it little),
# the power spans the road classes and varies from road to road
RATIO_FACTOR, LEVEL_FACTOR = 2.0, 10.0
# the reference: per road class of the run, REF_ROADS roads x REF_MASSES masses, at every noise level the run
# trained or was tested on
REF_ROADS, REF_MASSES = 8, 8
# windows averaged per reference recording at most: a recording's mean over more windows varies less, so a range
# over fewer is wider (never flags more) and bounds the reference's memory
REF_K_MAX = 16
SHOW = 5  # recording names a warning lists


@dataclass(frozen=True)
class TrainedRange:
    """The range of p = (p1, p2) the run's data span, whether a network estimates (else a least-squares
    baseline), the network's output bounds (None: unbounded) and the car's (C3, K3), which turn p into m3."""

    p_min: np.ndarray
    p_max: np.ndarray
    m3: tuple[float, float]  # data.m3_min, data.m3_max
    bound_lo: np.ndarray | None = None
    bound_hi: np.ndarray | None = None
    network: bool = True
    c3k3: tuple[float, float] = (615.0, 98935.0)

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi): a network's estimate at or below lo or at or above hi (each (2,), p1 and p2) is flagged: EDGE
        of the range's log width inside its edges."""
        step = (self.p_max / self.p_min) ** EDGE
        return self.p_min * step, self.p_max / step

    def outside(self, p: np.ndarray) -> np.ndarray:
        """(n,) bool: any of p1, p2 (rows of p, (n, 2)) near the trained range's edge or beyond (a baseline: more
        than RANGE_RTOL beyond), or at a network's output bound."""
        if self.network:
            lo, hi = self.edges()
            out = (p <= lo).any(axis=1) | (p >= hi).any(axis=1)
        else:
            out = (p < self.p_min * (1 - RANGE_RTOL)).any(axis=1) | (p > self.p_max * (1 + RANGE_RTOL)).any(axis=1)
        if self.bound_lo is not None:
            out |= (p <= self.bound_lo * (1 + BOUND_RTOL)).any(axis=1)
        if self.bound_hi is not None:
            out |= (p >= self.bound_hi * (1 - BOUND_RTOL)).any(axis=1)
        return out

    def describe(self) -> str:
        return (
            f"p1 {self.p_min[0]:.4g} to {self.p_max[0]:.4g} 1/s, p2 {self.p_min[1]:.4g} to {self.p_max[1]:.4g} "
            f"1/s^2 (data.m3_min to m3_max = {self.m3[0]:g} to {self.m3[1]:g} kg)"
        )


def trained_range(cfg: DictConfig, net=None) -> TrainedRange:
    """The run's p range (the prior its config derives from the car, the masses and the seat spread:
    ``${p_prior:...}``) and, for a network with a bounded head, that head's bounds as its weights hold them
    (model.base.Network.output_bounds)."""
    lo, hi = (np.array(p_prior(which, _root_=cfg)) for which in ("min", "max"))
    bounds = net.output_bounds() if net is not None else None
    bound_lo, bound_hi = bounds if bounds is not None else (None, None)
    car = QuarterCar(**cfg.get("car", {}))
    m3 = (float(cfg.data.m3_min), float(cfg.data.m3_max))
    return TrainedRange(lo, hi, m3, bound_lo, bound_hi, net is not None, (float(car.c3), float(car.k3)))


def resonance_band(p2_min: float, p2_max: float) -> tuple[float, float]:
    """The seat's natural frequencies sqrt(p2) / (2 pi) over the trained p2 range, in Hz."""
    return math.sqrt(p2_min) / (2 * math.pi), math.sqrt(p2_max) / (2 * math.pi)


def channel_features(windows: np.ndarray, dt: float, band: tuple[float, float]) -> np.ndarray:
    """(recordings, K, 2, w) windows -> (recordings, 2) features, both log10 of a power: the seat-to-body power
    ratio in ``band`` and the body acceleration's mean square, each averaged over the K windows first (Hann
    window, periodogram). Non-finite where a channel has no power."""
    w = windows.shape[-1]
    freqs = np.fft.rfftfreq(w, dt)
    in_band = (freqs >= band[0]) & (freqs <= band[1])
    if in_band.sum() < 2:  # short windows: the bins nearest the band
        step = freqs[1] - freqs[0]
        in_band = (freqs >= band[0] - step) & (freqs <= band[1] + step)
    spectra = np.abs(np.fft.rfft(windows * np.hanning(w), axis=-1)) ** 2
    power = spectra[..., in_band].sum(axis=-1).mean(axis=1)  # (recordings, 2)
    level = (windows[:, :, 1] ** 2).mean(axis=-1).mean(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([np.log10(power[:, 0] / power[:, 1]), np.log10(level)], axis=1)


class ChannelReference:
    """Recordings simulated as the run's training data were (its DatasetSpec: car, speed, amplitude, mass range,
    seat spread, measurement, dt), REF_ROADS roads x REF_MASSES masses for each of its road classes, with
    Gaussian noise at each level the run trained or was tested on (noise.train_std, noise.eval_std). A
    recording's features are compared with the range of theirs over the same K windows (``bounds``)."""

    def __init__(self, cfg: DictConfig, window: int, band: tuple[float, float]):
        spec = DatasetSpec.from_config(cfg)
        seat, body = [], []
        for c in spec.road_classes:  # every class of the run, evenly (a random draw of roads could miss one)
            ds = generate_dataset(replace(spec, road_classes=(c,), n_roads=REF_ROADS, n_masses=REF_MASSES))
            seat.append(ds.seat_acc.astype(np.float64))
            body.append(ds.body_acc.astype(np.float64))
        self.signals = np.stack([np.concatenate(seat), np.concatenate(body)], axis=1)  # (n, 2, steps)
        noise = cfg.get("noise", {})
        self.levels = sorted({0.0, float(noise.get("train_std", 0.0)), *(float(s) for s in noise.get("eval_std", []))})
        self.seed, self.dt, self.window, self.band = spec.seed, spec.dt, window, band
        self._bounds: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def bounds(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of the features of the reference recordings over K evenly spaced windows (at most REF_K_MAX
        and as many as they offer), widened by RATIO_FACTOR and LEVEL_FACTOR."""
        n, w = self.signals.shape[-1], self.window
        k = min(k, REF_K_MAX, n - w + 1)
        if k not in self._bounds:
            starts = window_starts(n, w, k)
            windows = np.stack([self.signals[:, :, s : s + w] for s in starts], axis=1)  # (n, K, 2, w)
            rng = np.random.default_rng([self.seed, 27, k])
            features = np.concatenate(
                [
                    channel_features(windows + std * rng.standard_normal(windows.shape), self.dt, self.band)
                    for std in self.levels
                ]
            )
            pad = np.log10([RATIO_FACTOR, LEVEL_FACTOR])
            self._bounds[k] = (np.nanmin(features, axis=0) - pad, np.nanmax(features, axis=0) + pad)
        return self._bounds[k]

    def outside(self, features: np.ndarray, k: int) -> np.ndarray:
        """(n,) bool: a feature of the recording (over K windows) beyond the widened range, or not finite."""
        lo, hi = self.bounds(k)
        return ~(np.isfinite(features).all(axis=1) & ((features >= lo) & (features <= hi)).all(axis=1))


def run_error(record: dict | None, windows: int) -> tuple[float | None, int | None, dict]:
    """The run's clean test error from its record: (the larger mean relative deviation of p1 and p2, the K of
    those rows, {parameter: value}); K is the largest the record holds up to ``windows``, else its smallest.
    (None, None, {}) when the record has no clean test rows, or one of them is no possible deviation (NaN, inf,
    below 0)."""
    rows = []
    for r in (record or {}).get("results", []) if isinstance(record, dict) else []:
        try:
            if r["split"] == "test" and float(r["noise_std"]) == 0 and r["parameter"] in ("p1", "p2"):
                rows.append((int(r["windows"]), r["parameter"], float(r["mean_rel_dev"])))
        except (KeyError, TypeError, ValueError):
            continue
    # a deviation that is not finite or below 0 measured nothing: the record cannot vouch for the run
    if not rows or not all(math.isfinite(v) and v >= 0 for _, _, v in rows):
        return None, None, {}
    ks = sorted({k for k, _, _ in rows})
    k = max([x for x in ks if x <= windows], default=ks[0])
    values = {p: v for kk, p, v in rows if kk == k}
    return max(values.values()), k, values


def names_of(names: list, mask: np.ndarray) -> str:
    flagged = [str(n) for n, m in zip(names, mask) if m]
    shown = ", ".join(flagged[:SHOW])
    return shown + (f", ... ({len(flagged) - SHOW} more)" if len(flagged) > SHOW else "")


def range_warning(mask: np.ndarray, names: list, trained: TrainedRange) -> str:
    k = int(mask.sum())
    head = f"{k} of {count(len(mask), 'recording')} ({names_of(names, mask)}) {'has' if k == 1 else 'have'} an estimate"
    if not trained.network:
        return (
            f"{head} more than {RANGE_RTOL:.0%} outside the trained range ({trained.describe()}) where the run was "
            "never tested (a least-squares fit does not saturate, but a negative or far-off value means the seat "
            f"equation does not fit the recording) (flag {RANGE})"
        )
    (lo1, lo2), (hi1, hi2) = trained.edges()
    m3_lo, m3_hi = trained.c3k3[0] / hi1, trained.c3k3[0] / lo1  # from p1; from p2 the same without seat spread
    return (
        f"{head} at the edge of the trained range or beyond it (m3 from p1 <= {m3_lo:.4g} or >= {m3_hi:.4g} kg; "
        f"p1 >= {hi1:.4g} or <= {lo1:.4g} 1/s, p2 >= {hi2:.4g} or <= {lo2:.4g} 1/s^2: within {EDGE:.0%} of the "
        f"range's log width of its edge; trained on {trained.describe()}): a network reads a "
        f"seat mass outside its trained range at or near the edge, so the true value may lie beyond the range "
        f"(flag {RANGE})"
    )


def channels_warning(mask: np.ndarray, names: list, reference: ChannelReference) -> str:
    lo, hi = reference.band
    k = int(mask.sum())
    return (
        f"{k} of {count(len(mask), 'recording')} ({names_of(names, mask)}) {'has' if k == 1 else 'have'} channel "
        f"powers unlike the run's training recordings (the seat-to-body power ratio at the seat resonance, "
        f"{lo:.3g} to {hi:.3g} Hz, "
        f"more than {RATIO_FACTOR:g}x, or the body acceleration's power more than {LEVEL_FACTOR:g}x beyond the "
        f"range of recordings simulated from the run's data spec): seat_acc and body_acc swapped, or a channel "
        f"not in m/s^2? (flag {CHANNELS})"
    )


def run_error_warning(error: float | None, k: int | None, values: dict, n: int) -> str:
    if error is None:
        on = f"{'the' if n == 1 else 'all'} {count(n, 'recording')}"
        return (
            f"about the run, not these recordings: the run's own test error is unknown (no readable metrics.json "
            f"with clean test results), so its estimates are unchecked (flag {RUN_ERROR} on {on})"
        )
    each = ", ".join(f"{p} {v:.1%}" for p, v in sorted(values.items()))
    return (
        f"about the run, not these recordings: the run's own clean test error is {error:.1%} mean relative "
        f"deviation (K = {k}: {each}) on its simulated test roads, above {RUN_ERROR_LIMIT:.0%}: expect errors of "
        f"that size on every recording it estimates (flag {RUN_ERROR} on all {n})"
    )
