"""Deprecated: the quadric-fit baseline moved to :mod:`heatcurv.testing` (:mod:`heatcurv.testing.baseline`).

Kept so that old scripts still run; importing it warns.  Use
``from heatcurv.testing import quadric_curvature`` (etc.) instead.
"""

import warnings

warnings.warn("heatcurv.baseline is deprecated; use heatcurv.testing", DeprecationWarning, stacklevel=2)

from .testing.baseline import RCOND_MIN, QuadricOptions, QuadricResult, quadric_curvature  # noqa: E402

__all__ = ["QuadricOptions", "QuadricResult", "quadric_curvature", "RCOND_MIN"]
