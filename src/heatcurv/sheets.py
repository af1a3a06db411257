"""Points whose ball holds the other side of a thin part: two sheets, not one.

A point's curvature and area come from its ball, read as one sheet of surface
with the point on it. Where a part is only a few spacings thick (a leg, an ear,
a wing, a thin plate) the ball also holds the part's other side: the fit mixes
two surfaces and the density counts both sides' points, so neither the
curvature nor the area is the sheet's. :func:`second_sheet` finds those points
from the oriented normals; they get no area and are not ``reliable``.

A neighbour ``q`` among the nearest of a point ``p`` (normals ``n_p``, ``n_q``)
lies on the other side when it is

* straight over or under ``p``: its height ``h = (q - p) . n_p`` is larger
  than its distance from ``p``'s normal line, and larger than half ``p``'s
  spacing (a neighbour on the same sheet lies in or near the tangent plane:
  more than 45 degrees out of it takes a quarter turn of the surface between
  them, which a resolved surface does not make within a few spacings), and
* facing the other way: ``n_p . n_q < -`` :data:`SHEET_ALIGNED` (the two sides
  of a thin part face away from each other, and both turn together when the
  part is inside out, so the test holds whichever side they were given).

Noise scatters one sheet's points over and under each other, but leaves their
normals alike, so it does not trip the test. A sheet lying right over a point
and facing the same way (a part whose one side alone is inside out, a stray
layer) is not counted: under noise it cannot be told from the scatter.
"""

from __future__ import annotations

import numpy as np

from ._kernels import segment as kernels
from .neighbourhood import Neighbourhood

__all__ = ["SHEET_ALIGNED", "SHEET_HEIGHT", "SHEET_NEIGHBOURS", "second_sheet"]

#: Nearest neighbours of each point looked at: the inner third of the operator's ball (60 by default,
#: radius about ``2 h``), where the fit's tapered heat weights are; beyond about ``1.2 h`` they fall
#: under a tenth of the centre's.
SHEET_NEIGHBOURS = 20
#: Smallest height over the tangent plane, in the point's spacings, of a neighbour on the other side.
SHEET_HEIGHT = 0.5
#: ``-n_p . n_q`` above which two normals face away from each other (within 60 degrees of opposite).
SHEET_ALIGNED = 0.5


def second_sheet(points: np.ndarray, normals: np.ndarray, nbhd: Neighbourhood, spacing: np.ndarray) -> np.ndarray:
    """Points with a neighbour on the other side of their part (module docstring), shape (n,), bool.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    normals : ndarray, shape (n, 3)
        Oriented unit normals (NaN rows: never flagged, never counted).
    nbhd : Neighbourhood
        The operator's neighbourhood; its :data:`SHEET_NEIGHBOURS` nearest of each row are used.
    spacing : ndarray, shape (n,)
        Each point's sampling spacing ``h`` (eq 2.6 / 2.7).

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    reach = nbhd.kth_distance(SHEET_NEIGHBOURS)
    found = kernels.opposite_sheet_counts(points, normals, nbhd.indptr, nbhd.indices, nbhd.distances, reach,
                                          SHEET_HEIGHT * np.asarray(spacing, dtype=np.float64), SHEET_ALIGNED)
    return found > 0
