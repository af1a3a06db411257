"""heatcurv (development placeholder; full exports restored when all modules exist)."""

from .errors import HeatcurvError
from .estimator import CurvatureResult, estimate

__version__ = "0.1.0"
