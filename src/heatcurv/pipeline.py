"""Deprecated: the options moved to :mod:`heatcurv.options`, the operator to :mod:`heatcurv.operator`."""

import warnings

from .operator import HeatKernelOperator, build_operator
from .options import METHODS, Options, resolve_options

__all__ = ["Options", "METHODS", "resolve_options", "HeatKernelOperator", "build_operator"]

warnings.warn(
    "heatcurv.pipeline is deprecated: use heatcurv.options and heatcurv.operator (or the top-level heatcurv names)",
    DeprecationWarning,
    stacklevel=2,
)
