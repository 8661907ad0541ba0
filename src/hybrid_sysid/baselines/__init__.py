"""Classical baselines without a network (``baseline=``), scored like a trained model (``predict_split``)."""

from hybrid_sysid.baselines.eiv_bayes import ErrorsInVariablesBayes
from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.baselines.least_squares import LeastSquaresFit, fit_p, lstsq_rows

__all__ = ["ErrorsInVariablesBayes", "ErrorsInVariablesFit", "LeastSquaresFit", "fit_p", "lstsq_rows"]
