"""Classical baselines without a network, evaluated like a trained model (``predict_split``)."""

from hybrid_sysid.physics.filters import bandpass_taps, check_bandpass, fir_valid
from hybrid_sysid.baselines.least_squares import LeastSquaresEstimator, fit_p, lstsq_rows


def is_baseline(target: str) -> bool:
    """Whether a model.net._target_ names an untrained estimator (``trainable = False``): train() then skips
    Lightning and evaluates it directly."""
    from hydra.utils import get_class

    try:
        return getattr(get_class(target), "trainable", True) is False
    except Exception:  # not a class (or not importable): instantiate() will report it
        return False


__all__ = ["LeastSquaresEstimator", "bandpass_taps", "check_bandpass", "fir_valid", "fit_p", "is_baseline",
           "lstsq_rows"]
