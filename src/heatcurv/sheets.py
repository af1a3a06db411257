"""Points whose neighbourhood holds a second sheet: the other side of a thin part, or a sheet over them.

A point's curvature and area come from its ball, read as one sheet of surface
with the point on it. Where a part is only a few spacings thick (a leg, an ear,
a thin plate, a wing) the ball also holds the part's other side, and where a
sheet's side was oriented wrongly another sheet can lie right in front of it.
Neither is one sheet: the fit mixes two surfaces, the density counts two sides'
points, and the side the normal points to is no longer backed by the
neighbourhood. :func:`second_sheet` finds those points from the oriented
normals alone; they get no area and are not ``reliable``.

A neighbour ``q`` of a point ``p`` (normals ``n_p``, ``n_q``) lies on a second
sheet when it is

* straight over or under ``p``: its height ``h = (q - p) . n_p`` is larger
  than its distance from ``p``'s normal line, and larger than half ``p``'s
  spacing (a neighbour on the same sheet lies in or near the tangent plane:
  more than 45 degrees out of it takes a quarter turn of the surface between
  them, which a resolved surface does not make within a few spacings), and
* on a sheet parallel to ``p``'s (``|n_p . n_q| >`` :data:`SHEET_ALIGNED`), and
* either facing the other way (``n_p . n_q < 0``: ``p`` and ``q`` are the two
  sides of a thin part, however both are oriented) or lying in front of ``p``
  (``h > 0``: a sheet facing the same way right over ``p``, so ``p`` faces
  into the part it bounds, or a stray layer in front of the surface).
"""

from __future__ import annotations

import numpy as np

from .neighbourhood import Neighbourhood

__all__ = ["SHEET_ALIGNED", "SHEET_HEIGHT", "SHEET_NEIGHBOURS", "second_sheet"]

#: Nearest neighbours of each point looked at: the inner part of the operator's ball (60), where a
#: second sheet changes the fit most.
SHEET_NEIGHBOURS = 20
#: Smallest height over the tangent plane, in the point's spacings, of a neighbour on a second sheet.
SHEET_HEIGHT = 0.5
#: ``|n_p . n_q|`` above which two normals lie on one axis (within 60 degrees).
SHEET_ALIGNED = 0.5


def second_sheet(points: np.ndarray, normals: np.ndarray, nbhd: Neighbourhood, spacing: np.ndarray) -> np.ndarray:
    """Points with a neighbour on a second sheet (module docstring), shape (n,), bool.

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
    near = nbhd.nearest(SHEET_NEIGHBOURS)
    rows, cols = near.rows, near.indices
    offset = points[cols] - points[rows]
    n_p = normals[rows]
    height = np.einsum("ij,ij->i", offset, n_p)
    lateral2 = np.maximum(np.einsum("ij,ij->i", offset, offset) - height**2, 0.0)
    aligned = np.einsum("ij,ij->i", normals[cols], n_p)
    with np.errstate(invalid="ignore"):
        over = (height**2 > lateral2) & (np.abs(height) > SHEET_HEIGHT * spacing[rows])
        second = over & (np.abs(aligned) > SHEET_ALIGNED) & ((aligned < 0) | (height > 0))
    return np.bincount(rows[second], minlength=nbhd.n_points) > 0
