"""Normals: PCA of the neighbourhood and one consistent orientation.

The paper (section 2.3) takes the normal from principal component analysis of
the ball neighbourhood; the sign of every curvature depends on the normal's
orientation, so the orientation must be consistent over the whole surface:

1. ``pca_normals``: the eigenvector of the smallest eigenvalue of each
   neighbourhood's covariance matrix.
2. ``orient_normals``: one consistent orientation, outward on closed
   surfaces (:mod:`heatcurv.orient.orientation`, which also orients up or towards
   a scanner, and flags what it cannot orient).
3. or ``orient_towards_viewpoint``: each normal faces a sensor position, point by point.
"""

from __future__ import annotations

import numpy as np

from .._kernels import segment as kernels
from ..errors import HeatcurvError
from ..geometry.neighbourhood import Neighbourhood
from ..operators.kernel import TAPER_START
from .orientation import GRAPH_NEIGHBOURS, as_viewpoint, orient

__all__ = [
    "pca_normals", "orient_normals", "orient_towards_viewpoint", "tangent_frames", "GRAPH_NEIGHBOURS", "as_viewpoint",
]



def pca_normals(
    points: np.ndarray, nbhd: Neighbourhood, weights: np.ndarray | None = None, *, taper: bool = False,
    roundness: bool = False, rows: np.ndarray | None = None, centres: np.ndarray | None = None,
) -> tuple[np.ndarray, ...]:
    """Unoriented PCA normals of the ball neighbourhoods.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    nbhd : Neighbourhood
        Neighbour pairs; each point's own position is included in its
        covariance (with weight 1).
    weights : ndarray, shape (nnz,), optional
        Weight of each neighbour in the covariance (default 1: the paper's
        plain PCA).
    taper : bool, optional
        Weight each neighbour by :func:`heatcurv.operators.kernel.ball_taper` (without
        storing it), which makes the normal a continuous function of the
        points. Not together with ``weights``.
    roundness : bool, optional
        Also return each ball's roundness (below).
    rows : ndarray of int, shape (r,), optional
        Only these rows' normals (the same numbers as the full computation's
        rows); then every output has ``r`` rows. Not together with ``weights``.
    centres : ndarray of int, shape (r,), optional
        Row ``i`` of ``nbhd`` is a ball about ``points[centres[i]]`` (a neighbourhood queried at
        other positions than its rows', e.g. anchors). Not together with ``weights`` or ``rows``.

    Returns
    -------
    normals : ndarray, shape (n, 3)
        Unit eigenvector of the smallest covariance eigenvalue.
    planarity : ndarray, shape (n,)
        ``(lambda_1 - lambda_0) / lambda_2`` with ``lambda_0 <= lambda_1 <= lambda_2``:
        near 1 for a clean surface patch, near 0 where the neighbourhood is
        not a surface (a line, a blob) and the normal is not defined.
    roundness : ndarray, shape (n,)
        With ``roundness=True``: ``lambda_0 / lambda_1``, near 0 for a disc of
        surface, near 1 where the ball's cross-section is round: the surface
        wraps around within it (a tube a few spacings across). NaN where
        ``lambda_1`` vanishes.
    """
    if weights is not None and taper:
        raise HeatcurvError("give pca_normals either weights or taper=True, not both")
    if rows is not None or centres is not None:
        if weights is not None or (rows is not None and centres is not None):
            raise HeatcurvError("give pca_normals at most one of weights or rows or centres")
        if rows is not None:
            centres = np.asarray(rows, dtype=np.int64)
            nbhd = nbhd.take_rows(centres)
        # the kernel reads row i's own point at points[i]: the centres' points go first
        centres = np.asarray(centres, dtype=np.int64)
        nbhd = Neighbourhood(nbhd.indptr, nbhd.indices.astype(np.int64) + centres.size, nbhd.distances, nbhd.radius,
                             nbhd.augmented, nbhd.by_distance)
        points = np.concatenate([points[centres], points])
    if weights is None:
        cov = kernels.weighted_covariances(
            points, nbhd.indptr, nbhd.indices, nbhd.distances, nbhd.radius, TAPER_START, taper
        )
        normals, evals = kernels.smallest_eigenvectors(cov)
        return (normals, _planarity(evals)) + ((_roundness(evals),) if roundness else ())

    # given weights (no compiled kernel takes them): numpy blocks of pairs, LAPACK's eigh
    def block_covariances(lo, hi, block):
        w = np.asarray(weights[nbhd.indptr[lo] : nbhd.indptr[hi]], dtype=np.float64)
        return _covariances(points, points[lo:hi], block, w)

    cov = nbhd.blockwise(block_covariances)
    evals, evecs = np.linalg.eigh(cov)
    return (evecs[:, :, 0], _planarity(evals)) + ((_roundness(evals),) if roundness else ())


def _roundness(evals):
    """``lambda_0 / lambda_1`` of ascending eigenvalues, NaN where ``lambda_1`` vanishes."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(evals[:, 1] > 0, evals[:, 0] / evals[:, 1], np.nan)


def _planarity(evals):
    """``(lambda_1 - lambda_0) / lambda_2`` of ascending eigenvalues, 0 where all vanish."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(evals[:, 2] > 0, (evals[:, 1] - evals[:, 0]) / evals[:, 2], 0.0)


def _covariances(points, centres, nbhd, w):
    """Weighted covariance of each neighbourhood and its centre (weight 1), shape (m, 3, 3)."""
    rows = nbhd.rows
    total = nbhd.segment_sum(w) + 1.0
    # weighted neighbourhood mean including the point itself
    mean = (nbhd.segment_sum(w[:, None] * points[nbhd.indices]) + centres) / total[:, None]
    d = points[nbhd.indices] - mean[rows]
    d0 = centres - mean
    # the six distinct covariance entries one at a time: no (pairs x 9) temporary
    cov = np.empty((nbhd.n_points, 3, 3))
    for a, b in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)):
        entry = (nbhd.segment_sum(w * d[:, a] * d[:, b]) + d0[:, a] * d0[:, b]) / total
        cov[:, a, b] = cov[:, b, a] = entry
    return cov


def orient_normals(
    points: np.ndarray,
    normals: np.ndarray,
    nbhd: Neighbourhood,
    areas: np.ndarray | None = None,
    graph_neighbours: int | None = GRAPH_NEIGHBOURS,
) -> np.ndarray:
    """Give unoriented normals one consistent orientation, outward on closed surfaces.

    The ``"outward"`` policy of :func:`heatcurv.orient.orientation.orient`, which
    also reports the points it could not orient; see there for ``"up"`` and
    ``"viewpoint"``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    normals : ndarray, shape (n, 3)
        Unit normals of arbitrary sign.
    nbhd : Neighbourhood
        Neighbour graph the orientation is propagated over.
    areas : ndarray, shape (n,), optional
        Per-point areas for the outward vote (equal weights if omitted).
    graph_neighbours : int or None, optional
        Propagate over ``graph_neighbours`` of each point's neighbours only
        (None: all); see :func:`heatcurv.orient.orientation.orient`.

    Returns
    -------
    ndarray, shape (n, 3)
        The normals, flipped where needed. Per connected component of the
        neighbour graph: outward (away from the component's centroid in the
        mean, ``sum_i A_i n_i . (x_i - c) > 0``) when that vote is clear, which
        holds for closed surfaces and for bowls and caps; for nearly flat open
        patches, where the vote is below 10 % of ``sum_i A_i |n_i . (x_i - c)|``,
        the mean normal is made to point along the positive side of the
        component's least-variance axis (whose largest coordinate is made positive).
    """
    return orient(points, normals, nbhd, areas, mode="outward", graph_neighbours=graph_neighbours).normals


def orient_towards_viewpoint(points: np.ndarray, normals: np.ndarray, viewpoint) -> np.ndarray:
    """Flip each normal to face a sensor position, ``n_i . (v - x_i) > 0``, point by point.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Points, in the same frame as ``viewpoint``.
    normals : ndarray, shape (n, 3)
        Unit normals.
    viewpoint : array_like, shape (3,) or (n, 3)
        Scanner position, or one per point.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    v = as_viewpoint(viewpoint, points.shape[0])
    facing = np.einsum("ij,ij->i", normals, v - points)
    return np.where(facing[:, None] < 0, -normals, normals)


def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An orthonormal tangent basis ``(e1, e2)`` at each point with ``e1 x e2 = n``.

    Parameters
    ----------
    normals : ndarray, shape (n, 3)
        Unit normals.

    Returns
    -------
    e1, e2 : ndarray, shape (n, 3)
    """
    # cross with the coordinate axis least aligned with n: never degenerate
    axis = np.zeros_like(normals)
    axis[np.arange(normals.shape[0]), np.argmin(np.abs(normals), axis=1)] = 1.0
    e1 = np.cross(axis, normals)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(normals, e1)
    return e1, e2
