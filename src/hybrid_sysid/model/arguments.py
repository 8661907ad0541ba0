"""The torch-free part of building the package's networks and objectives: each function checks its class's
arguments (same names, same defaults) and returns what the constructor needs of them, so that the constructor
calls it and config validation calls it first (``TORCH_FREE``), before torch is imported. A refused ``model.net`` or
``objective`` value then costs a fraction of a second of CPU instead of torch's two (docs/reliability/).

tests/model/test_arguments.py holds each function's signature to its class's.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

from hybrid_sysid.core.checks import ConfigError, bad, check_choice, check_int, check_number, check_pair
from hybrid_sysid.core.options import (
    ACTIVATIONS,
    DOWNSAMPLES,
    MEASUREMENTS,
    OUTSIDE_TARGETS,
    TARGETS,
    WEIGHTINGS,
)
from hybrid_sysid.data.spec import MIN_FILTERED
from hybrid_sysid.physics.filters import filter_taps

# weights of a network at most: 400 MB of float32, 1.6 GB with their gradients and Adam's two moments; far above
# either network's defaults (about 30 thousand and 6 million), and a typo's 10^9 channels is refused before torch
# tries to allocate it
WEIGHTS_MAX = 10**8
LAYERS_MAX = 30  # FastCNN: each layer halves the window, which must keep 2^n_layers steps
PAPER_SHORTEST = 59  # PaperCNN: both 'valid' convolutions need 50 + 10 - 1 samples
# the least-squares baseline's band (conf/baseline/ls_bandpass.yaml): it keeps the seat resonance and drops the drift
# of integrated noise below it and the white noise above it
DEFAULT_FILTER = {"low_hz": 4.0, "high_hz": 20.0, "taps": 151}
ANCHORS = ("eiv", "ls")


def check_weights(key: str, value, weights: int, how: str) -> None:
    """The network's ``weights`` (``how``: the formula, in its arguments' names) are at most WEIGHTS_MAX."""
    if weights > WEIGHTS_MAX:
        here = f"{weights:.3g}" if weights < 10**18 else "over 1e18"  # a float could not hold 10^300 x 10^300
        bad(key, value, f"{how} must be at most {WEIGHTS_MAX:.0e} weights (here {here})")


def checked_layers(n_layers) -> int:
    """n_layers, checked before 2^n_layers is computed: 10^30 layers would hold the process in that power."""
    n_layers = check_int("n_layers", n_layers, 1)
    if n_layers > LAYERS_MAX:
        bad("n_layers", n_layers, f"must lie in [1, {LAYERS_MAX}] (each layer halves the window)")
    return n_layers


def paper_cnn(p_scale: Sequence[float], window: int = 500, activation: str = "tanh") -> tuple[int, tuple, int]:
    """PaperCNN's checked window, p_scale and flattened feature count."""
    window = check_int("window", window, PAPER_SHORTEST)
    check_choice("activation", activation, ACTIVATIONS)
    p_scale = check_pair("p_scale", p_scale)
    flat = 100 * (window - 50 + 1 - 10 + 1)
    check_weights("window", window, flat * 100, "its first dense layer, 100 x 100 x (window - 58),")
    return window, p_scale, flat


def paper_cnn_window(window: int = 500, **arguments) -> tuple[int, int | None]:
    """It reads windows of its ``window`` steps alone: the flattened features size its first dense layer."""
    return window, window


class CNNArguments(NamedTuple):
    channels: int
    n_layers: int
    kernel_size: int
    lo: tuple
    hi: tuple


def fast_cnn(
    p_min: Sequence[float],
    p_max: Sequence[float],
    channels: int = 32,
    n_layers: int = 4,
    kernel_size: int = 9,
    margin: float = 0.1,
    bn_momentum: float = 0.01,
    downsample: str = "stride",
) -> CNNArguments:
    """FastCNN's checked sizes and prior range."""
    channels = check_int("channels", channels, 1)
    n_layers = checked_layers(n_layers)
    kernel_size = check_int("kernel_size", kernel_size, 1)
    if kernel_size % 2 == 0:
        bad("kernel_size", kernel_size, "an odd integer (for 'same' padding)")
    how = "channels x (3 + (n_layers - 1) x channels) x kernel_size"
    check_weights("channels", channels, channels * (3 + (n_layers - 1) * channels) * kernel_size, how)
    check_number("margin", margin, 0, 1)
    check_number("bn_momentum", bn_momentum, 0, 1, low_open=True)
    check_choice("downsample", downsample, DOWNSAMPLES)
    lo, hi = check_pair("p_min", p_min), check_pair("p_max", p_max)
    if not all(a < b for a, b in zip(lo, hi)):
        bad("p_max", list(p_max), f"above p_min = {list(p_min)} for each parameter")
    return CNNArguments(channels, n_layers, kernel_size, lo, hi)


def fast_cnn_window(n_layers: int = 4, **arguments) -> tuple[int, None]:
    """Any window of at least 2^n_layers steps: each layer halves the sequence, which must keep a sample."""
    return 2 ** checked_layers(n_layers), None


class AnchoredArguments(NamedTuple):
    cnn: CNNArguments
    band: dict
    fir: object  # the least-squares band-pass's taps (float64 numpy)
    eiv: object  # the likelihood anchor (ErrorsInVariablesFit) or None
    map: object  # the MAP fit of the prior (ErrorsInVariablesFit) or None
    bayes: object  # the blend's Bayes estimate (ErrorsInVariablesBayes) or None
    blend: float | None


def anchored(
    p_min: Sequence[float],
    p_max: Sequence[float],
    dt: float,
    measurement: str = "consistent",
    filter: dict | None = None,
    tau_min: float = 1e-3,
    tau_max: float = 1.0,
    anchor: str = "ls",
    fix: str = "none",
    prior: dict | None = None,
    trunk: bool = True,
    blend: float | None = None,
    partner: bool = False,
    **cnn,
) -> AnchoredArguments:
    """AnchoredCNN's checked arguments and its fits (numpy objects, without weights)."""
    # deferred: the likelihood fits are only needed by this network
    from hybrid_sysid.baselines.eiv_bayes import ErrorsInVariablesBayes
    from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
    from hybrid_sysid.physics.faults import fix_code

    checked_cnn = fast_cnn(p_min, p_max, **cnn)
    check_choice("measurement", measurement, MEASUREMENTS)
    check_choice("anchor", anchor, ANCHORS)
    fix_code(fix)  # a registered fix (physics.faults.fixes), else a ConfigError naming fix
    check_number("tau_min", tau_min, 0, 1, low_open=True)
    if not (isinstance(tau_max, (int, float)) and tau_min < tau_max <= 10):
        bad("tau_max", tau_max, f"must lie in (tau_min = {tau_min:g}, 10]")
    band = dict(DEFAULT_FILTER if filter is None else filter)
    fir = filter_taps(band, dt)
    # a fault's fix only when there is one, so a clean config needs nothing of the fit beyond its band
    extra = {} if fix == "none" else {"fix": fix}
    eiv = ErrorsInVariablesFit(noise_ratio=1.0, dt=float(dt), **band, **extra) if anchor == "eiv" else None
    # the fit checks the prior (a dict of its keys), and names its errors under model.net.prior
    fit_map = None
    if prior is not None:
        fit_map = ErrorsInVariablesFit(noise_ratio=1.0, prior=prior, dt=float(dt), **band, **extra)
    if blend is not None:
        blend = check_number("blend", blend, 0.0, 1.0)
    bayes = None
    if blend is not None and prior is not None and fix == "none" and prior.get("seat_spread", 0) > 0:
        bayes = ErrorsInVariablesBayes(noise_ratio=1.0, prior=prior, dt=float(dt), **band)
    if not isinstance(trunk, bool):
        bad("trunk", trunk, "true or false")
    if not isinstance(partner, bool):
        bad("partner", partner, "true or false")
    if partner and prior is None:
        bad("partner", partner, "false without a prior (its share follows the noise the MAP fit's likelihood finds)")
    return AnchoredArguments(checked_cnn, band, fir, eiv, fit_map, bayes, blend)


def anchored_window(n_layers: int = 4, filter: dict | None = None, **arguments) -> tuple[int, None]:
    """Long enough for the trunk and for the band-pass to leave MIN_FILTERED samples to fit."""
    taps = (DEFAULT_FILTER if filter is None else filter).get("taps", DEFAULT_FILTER["taps"])
    return max(2 ** int(n_layers), int(taps) + MIN_FILTERED - 1), None


def labelled(p_scale: Sequence[float]) -> tuple:
    """LabelledObjective's checked p_scale."""
    return check_pair("p_scale", p_scale)


class HybridArguments(NamedTuple):
    filter: dict | None
    fir: object  # the band-pass taps (float64 numpy), None without a filter
    p_scale: tuple | None


def hybrid(
    normalize: bool = True,
    filter: dict | None = None,
    weighting: str = "none",
    dt: float | None = None,
    measurement: str = "consistent",
    target: str = "residual",
    p_scale: Sequence[float] | None = None,
) -> HybridArguments:
    """HybridObjective's checked arguments and band-pass."""
    check_choice("target", target, TARGETS)
    check_choice("weighting", weighting, WEIGHTINGS)
    if target != "residual" and p_scale is None:
        raise ConfigError("p_scale", missing=True, allowed=f"target = {target!r} needs it (${{p_prior:scale}})")
    if target != "residual" and weighting != "none":
        bad("weighting", weighting, f"none with target = {target!r}")
    if p_scale is not None:
        p_scale = check_pair("p_scale", p_scale)
    if weighting == "eiv" and filter is None:
        bad("weighting", weighting, "none without a filter (unfiltered, integrated noise has no finite variance)")
    filter = dict(filter) if filter is not None else None
    fir = None
    if filter is not None:
        if dt is None:
            raise ConfigError("dt", missing=True, allowed="a filtered objective needs the data's step (${data.dt})")
        fir = filter_taps(filter, dt)
    return HybridArguments(filter, fir, p_scale)


def combined(
    p_scale: Sequence[float],
    labelled_weight: float = 1.0,
    hybrid_weight: float = 1.0,
    normalize: bool = True,
    filter: dict | None = None,
    weighting: str = "none",
    dt: float | None = None,
    measurement: str = "consistent",
) -> HybridArguments:
    """CombinedObjective's checked weights, then its two objectives' arguments (the hybrid one's returned)."""
    check_number("labelled_weight", labelled_weight, 0)
    check_number("hybrid_weight", hybrid_weight, 0)
    if labelled_weight == 0 and hybrid_weight == 0:
        bad("hybrid_weight", hybrid_weight, "labelled_weight and hybrid_weight must not both be zero")
    labelled(p_scale)
    return hybrid(normalize=normalize, filter=filter, weighting=weighting, dt=dt, measurement=measurement)


class CrossSegmentArguments(NamedTuple):
    p_scale: tuple
    floor: float
    filter: dict
    outside_fir: object  # the outside fit's band-pass taps (float64 numpy)


def cross_segment(
    p_scale: Sequence[float],
    filter: dict,
    dt: float | None = None,
    floor: float = 0.01,
    target: str = "ls",
    weighted: bool = True,
    fix: str = "none",
) -> CrossSegmentArguments:
    """CrossSegmentObjective's checked arguments and the outside fit's band-pass."""
    p_scale = check_pair("p_scale", p_scale)
    floor = check_number("floor", floor, 0, low_open=True, unit="a relative standard error")
    if dt is None:
        raise ConfigError("dt", missing=True, allowed="the band-pass needs the data's step (${data.dt})")
    filter = dict(filter)
    check_choice("target", target, OUTSIDE_TARGETS)
    outside_fir = filter_taps(filter, dt)
    if not isinstance(weighted, bool):
        raise ConfigError("weighted", weighted, allowed="true or false")
    from hybrid_sysid.physics.faults import fix_code  # here: the registry loads the faults' plugins

    fix_code(fix)
    return CrossSegmentArguments(p_scale, floor, filter, outside_fir)


# the package's own classes: their torch-free part, and a network's window bounds
TORCH_FREE = {
    "hybrid_sysid.model.networks.PaperCNN": (paper_cnn, paper_cnn_window),
    "hybrid_sysid.model.networks.FastCNN": (fast_cnn, fast_cnn_window),
    "hybrid_sysid.model.anchored.AnchoredCNN": (anchored, anchored_window),
    "hybrid_sysid.model.objectives.LabelledObjective": (labelled, None),
    "hybrid_sysid.model.objectives.HybridObjective": (hybrid, None),
    "hybrid_sysid.model.objectives.CombinedObjective": (combined, None),
    "hybrid_sysid.model.cross_segment.CrossSegmentObjective": (cross_segment, None),
}
