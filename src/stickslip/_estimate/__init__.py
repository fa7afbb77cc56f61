"""Level-crossing statistics: exact Gaussian formulas, closures and series approximations."""

from .estimator import ApproximationWarning as ApproximationWarning
from .estimator import CrossingEstimator as CrossingEstimator
