"""Test support: error measures against exact values, the quadric-fit baseline, the real scans.

Not part of the estimator: what the tests, the benchmarks and the demo use to
judge an estimate against the exact values of :mod:`heatcurv.surfaces`.

=====================  ======================================================
``errors``             error measures (eqs 4.1, 5.1, relative L1) and
                       :func:`compare` (formerly ``heatcurv.evaluation``)
``baseline``           the classical k-NN quadric fit, for comparison
                       (formerly ``heatcurv.baseline``), at every point
                       or at chosen centres only (``centres=``)
``scans``              the real-scan test set: pymeshlab's sample meshes,
                       fetched (never shipped), and a mesh reader giving
                       their areas, normals and components
``terminal``           run a command with stderr on a pseudo-terminal, as
                       in a user's shell (the compile notice's test, the
                       first-run benchmark)
=====================  ======================================================
"""

from __future__ import annotations

from .baseline import RCOND_MIN, QuadricOptions, QuadricResult, quadric_curvature
from .errors import (
    aligned_exact,
    compare,
    default_margin,
    direction_error_deg,
    neighbour_margin,
    paper_error,
    relative_l1,
)

__all__ = [
    "QuadricOptions",
    "QuadricResult",
    "RCOND_MIN",
    "aligned_exact",
    "compare",
    "default_margin",
    "direction_error_deg",
    "neighbour_margin",
    "paper_error",
    "quadric_curvature",
    "relative_l1",
]
