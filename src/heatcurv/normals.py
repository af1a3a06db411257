"""Normals: PCA of the neighbourhood and one consistent orientation.

The paper (section 2.3) takes the normal from principal component analysis of
the ball neighbourhood; the sign of every curvature depends on the normal's
orientation, so the orientation must be consistent over the whole surface:

1. ``pca_normals``: the eigenvector of the smallest eigenvalue of each
   neighbourhood's covariance matrix.
2. ``orient_normals``: propagate one orientation over a minimum spanning tree
   of the neighbour graph (Hoppe et al. 1992: edges cost ``1 - |n_i . n_j|``,
   so the propagation crosses flat, well-aligned regions first), then choose
   each connected component's global sign: outward for closed surfaces,
   i.e. ``sum_i A_i n_i . (x_i - c) > 0`` (this sum is 3 x volume > 0 for an
   outward-oriented closed surface); see :func:`orient_normals` for open ones.
3. or ``orient_towards_viewpoint``: each normal faces a sensor position.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from ._kernels import segment as kernels
from .errors import HeatcurvError
from .kernel import TAPER_START
from .neighbourhood import Neighbourhood

__all__ = ["pca_normals", "orient_normals", "orient_towards_viewpoint", "tangent_frames", "GRAPH_NEIGHBOURS"]

#: Nearest neighbours per point in the orientation's spanning-tree graph.
GRAPH_NEIGHBOURS = 10
#: Deprecated spelling of :data:`GRAPH_NEIGHBOURS`.
GRAPH_NEIGHBORS = GRAPH_NEIGHBOURS
_UNSET = object()


def pca_normals(
    points: np.ndarray, nbhd: Neighbourhood, weights: np.ndarray | None = None, *, taper: bool = False
) -> tuple[np.ndarray, np.ndarray]:
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
        Weight each neighbour by :func:`heatcurv.kernel.ball_taper` (without
        storing it), which makes the normal a continuous function of the
        points. Not together with ``weights``.

    Returns
    -------
    normals : ndarray, shape (n, 3)
        Unit eigenvector of the smallest covariance eigenvalue.
    planarity : ndarray, shape (n,)
        ``(lambda_1 - lambda_0) / lambda_2`` with ``lambda_0 <= lambda_1 <= lambda_2``:
        near 1 for a clean surface patch, near 0 where the neighbourhood is
        not a surface (a line, a blob) and the normal is not defined.
    """
    if weights is not None and taper:
        raise HeatcurvError("give pca_normals either weights or taper=True, not both")
    if weights is None:
        cov = kernels.weighted_covariances(
            points, nbhd.indptr, nbhd.indices, nbhd.distances, nbhd.radius, TAPER_START, taper
        )
        normals, evals = kernels.smallest_eigenvectors(cov)
        return normals, _planarity(evals)

    # given weights (no compiled kernel takes them): numpy blocks of pairs, LAPACK's eigh
    def block_covariances(lo, hi, block):
        w = np.asarray(weights[nbhd.indptr[lo] : nbhd.indptr[hi]], dtype=np.float64)
        return _covariances(points, points[lo:hi], block, w)

    cov = nbhd.blockwise(block_covariances)
    evals, evecs = np.linalg.eigh(cov)
    return evecs[:, :, 0], _planarity(evals)


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


def _flip_parity_along_tree(pred: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """Parity of flips accumulated from each node up to its tree root.

    ``pred[i]`` is the parent of ``i`` (a root points to itself) and ``flip[i]``
    says whether ``i`` disagrees with its parent. Pointer jumping: O(n log depth),
    vectorised.
    """
    parity = flip.copy()
    ptr = pred.copy()
    while True:
        parent = ptr[ptr]
        if np.array_equal(parent, ptr):
            break
        parity = parity ^ parity[ptr]
        ptr = parent
    return parity


def orient_normals(
    points: np.ndarray,
    normals: np.ndarray,
    nbhd: Neighbourhood,
    areas: np.ndarray | None = None,
    graph_neighbours: int | None = GRAPH_NEIGHBOURS,
    *,
    graph_neighbors=_UNSET,
) -> np.ndarray:
    """Give unoriented normals one consistent orientation.

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
        (None: all): the nearest half and the rest spread out to the ball's
        edge (:meth:`heatcurv.neighbourhood.Neighbourhood.spread`), so the
        graph is as connected as the ball's even on anisotropic scans. The
        spanning tree follows short, aligned edges anyway; a sparser graph
        makes it several times cheaper (measured on a million points: 13 s
        with 60 neighbours, 1.9 s with 10).
    graph_neighbors : int or None, optional
        Deprecated alias of ``graph_neighbours``.

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
    if graph_neighbors is not _UNSET:
        warnings.warn("orient_normals: graph_neighbors= is deprecated, use graph_neighbours=", DeprecationWarning,
                      stacklevel=2)
        graph_neighbours = graph_neighbors
    n = points.shape[0]
    if graph_neighbours is not None:
        nbhd = nbhd.spread(int(graph_neighbours))
    # cost: misalignment first, distance (relative to the ball) as tie-breaker;
    # strictly positive because csgraph treats zero entries as missing edges
    cost = kernels.orientation_costs(normals, nbhd.indptr, nbhd.indices, nbhd.distances, nbhd.radius)
    graph = sp.csr_matrix((cost, nbhd.indices, nbhd.indptr), shape=(n, n))
    # csgraph takes every stored entry as an undirected edge: the directed neighbour
    # graph needs no symmetrising (which doubled the edges Kruskal sorts: 5.6 s -> 2.3 s
    # on a million points); of a mutual pair's two costs the cheaper counts
    tree = csgraph.minimum_spanning_tree(graph)
    tree = tree + tree.T
    n_comp, labels = csgraph.connected_components(tree, directed=False)
    # virtual root n joined to the first node of every component, so one BFS covers the forest
    reps = np.unique(labels, return_index=True)[1]
    link = sp.csr_matrix((np.ones(reps.size), (np.full(reps.size, n), reps)), shape=(n + 1, n + 1))
    forest = sp.bmat([[tree, None], [None, sp.csr_matrix((1, 1))]]).tocsr() + link + link.T
    _, pred = csgraph.breadth_first_order(forest, n, directed=False, return_predecessors=True)
    pred = pred[:n].astype(np.int64)
    is_root = pred == n
    pred[is_root] = np.flatnonzero(is_root)
    flip = np.einsum("ij,ij->i", normals, normals[pred]) < 0
    flip[is_root] = False
    parity = _flip_parity_along_tree(pred, flip)
    oriented = np.where(parity[:, None], -normals, normals)

    # global sign of each component
    w = np.ones(n) if areas is None else np.abs(areas)
    count = np.bincount(labels, weights=w, minlength=n_comp)
    centroid = np.stack([np.bincount(labels, weights=w * points[:, k], minlength=n_comp) for k in range(3)], 1)
    centroid /= count[:, None]
    radial = np.einsum("ij,ij->i", oriented, points - centroid[labels]) * w
    vote = np.bincount(labels, weights=radial, minlength=n_comp)
    strength = np.bincount(labels, weights=np.abs(radial), minlength=n_comp)
    sign = np.where(vote < 0, -1.0, 1.0)
    weak = np.abs(vote) < 0.1 * strength
    for c in np.flatnonzero(weak):  # nearly flat patches: few components, small loop
        member = labels == c
        rel = points[member] - centroid[c]
        axis = np.linalg.svd(rel, full_matrices=False)[2][-1]
        axis = axis * np.sign(axis[np.argmax(np.abs(axis))])
        sign[c] = -1.0 if oriented[member].sum(axis=0) @ axis < 0 else 1.0
    return oriented * sign[labels][:, None]


def orient_towards_viewpoint(points: np.ndarray, normals: np.ndarray, viewpoint) -> np.ndarray:
    """Flip each normal to face a sensor position, ``n_i . (v - x_i) > 0``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Points, in the same frame as ``viewpoint``.
    normals : ndarray, shape (n, 3)
        Unit normals.
    viewpoint : array_like, shape (3,)
        Scanner position.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    v = as_viewpoint(viewpoint)
    facing = np.einsum("ij,ij->i", normals, v - points)
    return np.where(facing[:, None] < 0, -normals, normals)


def as_viewpoint(viewpoint) -> np.ndarray:
    """Validate a sensor position: 3 finite numbers, returned as a float64 array of shape (3,)."""
    try:
        v = np.asarray(viewpoint, dtype=np.float64)
    except (TypeError, ValueError):
        v = np.empty(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise HeatcurvError(f"viewpoint must be 3 finite numbers (x, y, z), got {viewpoint!r}")
    return v


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
