"""Border points of open surfaces.

Near the border of an open surface (a scan's edge, a hole) a point's ball is
cut on one side. Every estimator suffers there (the paper, section 4: "near
the boundary ... the principal directions follow the edges"), so heatcurv
marks those points instead of pretending. The test is the offset of the
neighbours' centroid in the tangent plane: in the interior of a uniformly
sampled surface it is ``O(R / sqrt(k))``; at a straight border the ball is a
half disc, whose centroid lies ``4 R / (3 pi) = 0.42 R`` inside.
"""

from __future__ import annotations

import numpy as np

from .._kernels import segment as kernels
from ..errors import HeatcurvError
from ..geometry.neighbourhood import Neighbourhood
from ..operators.kernel import TAPER_START
from ..tuning import TUNING

__all__ = ["centroid_offset", "border_points"]


def centroid_offset(
    points: np.ndarray,
    nbhd: Neighbourhood,
    normals: np.ndarray,
    weights: np.ndarray | None = None,
    *,
    taper: bool = False,
    centres: np.ndarray | None = None,
) -> np.ndarray:
    """Tangential offset of each ball's centroid from its centre, in ball radii.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points; ``nbhd.indices`` index them.
    nbhd : Neighbourhood
        Ball neighbourhoods (``nbhd.radius`` is the ball radius), one row per centre.
    normals : ndarray, shape (m, 3)
        Unit normals of the centres.
    weights : ndarray, shape (nnz,), optional
        Weight of each neighbour in the centroid (default 1).
    taper : bool, optional
        Weight each neighbour by :func:`heatcurv.operators.kernel.ball_taper` instead
        (computed pair by pair, not stored). Not together with ``weights``.
    centres : ndarray, shape (m, 3), optional
        The balls' centres (default ``points``).

    Returns
    -------
    ndarray, shape (m,)
        ``|P_t (mean_j x_j - x_i)| / R_i`` with ``P_t`` the projection onto the
        tangent plane.
    """
    if weights is not None and taper:
        raise HeatcurvError("give centroid_offset either weights or taper=True, not both")
    if centres is None:
        centres = points
    if weights is None:
        return kernels.centroid_offsets(
            points, centres, nbhd.indptr, nbhd.indices, nbhd.distances, nbhd.radius, normals, TAPER_START, taper
        )

    # given weights (no compiled kernel takes them): numpy blocks of pairs
    def block_offsets(lo, hi, block):
        w = np.asarray(weights[nbhd.indptr[lo] : nbhd.indptr[hi]], dtype=np.float64)
        total = np.maximum(block.segment_sum(w), np.finfo(float).tiny)
        centroid = block.segment_sum(w[:, None] * points[block.indices]) / total[:, None] - centres[lo:hi]
        centroid -= np.einsum("ij,ij->i", centroid, normals[lo:hi])[:, None] * normals[lo:hi]
        return np.linalg.norm(centroid, axis=1) / block.radius

    return nbhd.blockwise(block_offsets)


def border_points(
    points: np.ndarray,
    nbhd: Neighbourhood,
    normals: np.ndarray,
    threshold: float = TUNING.border_offset,
    weights=None,
    *,
    taper: bool = False,
    centres: np.ndarray | None = None,
) -> np.ndarray:
    """Points whose ball is cut by a border of the surface.

    Returns
    -------
    ndarray, shape (m,), bool
        ``centroid_offset > threshold`` (see :func:`centroid_offset` for the
        other parameters).
    """
    return centroid_offset(points, nbhd, normals, weights, taper=taper, centres=centres) > threshold
