"""Ball neighbourhoods ``B_r(x_i) = {x_j : |xi - xj| <= r_i}`` as flat CSR arrays.

The paper (section 2) sums every operator over the ball of radius
``r = alpha h`` (``3.5 <= alpha <= 4.5``). The neighbourhood is computed once
and shared by every later stage (areas, Laplacian, normals, principal fit),
stored as CSR arrays: the neighbours of point ``i`` are
``indices[indptr[i]:indptr[i+1]]`` at distances ``distances[...]``. The point
itself is not stored; stages that need the diagonal (the area system) add it.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

from .errors import HeatcurvError

__all__ = ["Neighbourhood", "ball_neighbourhood"]


@dataclass(frozen=True)
class Neighbourhood:
    """Neighbour lists of a point cloud in CSR form.

    Attributes
    ----------
    indptr : ndarray, shape (n + 1,), int64
        Row pointers.
    indices : ndarray, shape (nnz,), int32 or int64
        Neighbour indices, ascending within each row; the point itself excluded.
    distances : ndarray, shape (nnz,), float64
        ``|x_i - x_j|`` for each stored pair.
    radius : ndarray, shape (n,), float64
        Ball radius used for each point.
    augmented : ndarray, shape (n,), bool
        Points whose ball held fewer than ``min_neighbors`` points and were
        given their nearest neighbours instead (isolated points, sparse edges).
    """

    indptr: np.ndarray
    indices: np.ndarray
    distances: np.ndarray
    radius: np.ndarray
    augmented: np.ndarray

    @property
    def n_points(self) -> int:
        return int(self.indptr.shape[0] - 1)

    @property
    def n_pairs(self) -> int:
        return int(self.indices.shape[0])

    @property
    def counts(self) -> np.ndarray:
        """Number of neighbours of each point, shape ``(n,)``."""
        return np.diff(self.indptr)

    @property
    def rows(self) -> np.ndarray:
        """Row (centre point) of every stored pair, shape ``(nnz,)``."""
        return np.repeat(np.arange(self.n_points, dtype=self.indices.dtype), self.counts)

    def segment_sum(self, values: np.ndarray) -> np.ndarray:
        """Sum per-pair ``values`` (shape ``(nnz,)`` or ``(nnz, k)``) over each row.

        Returns
        -------
        ndarray, shape (n,) or (n, k)
        """
        out = np.zeros((self.n_points,) + values.shape[1:], dtype=np.result_type(values, np.float64))
        nonempty = self.counts > 0
        if values.shape[0]:
            out[nonempty] = np.add.reduceat(values, self.indptr[:-1][nonempty], axis=0)
        return out


def _index_dtype(n: int):
    return np.int32 if n < np.iinfo(np.int32).max else np.int64


def ball_neighbourhood(
    points: np.ndarray,
    radius,
    tree: cKDTree | None = None,
    min_neighbors: int = 6,
    workers: int = -1,
) -> Neighbourhood:
    """All neighbours within ``radius`` of each point, in CSR form.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    radius : float or ndarray, shape (n,)
        Ball radius ``r_i = alpha h_i``; a scalar gives the symmetric
        neighbourhood of the paper's global spacing.
    tree : scipy.spatial.cKDTree, optional
        A tree already built on ``points``.
    min_neighbors : int, optional
        A point whose ball holds fewer neighbours gets its ``min_neighbors``
        nearest ones instead and is marked in ``augmented``; without it,
        isolated points would have no normal and no curvature.
    workers : int, optional
        Threads for the k-d tree queries.

    Returns
    -------
    Neighbourhood
    """
    n = points.shape[0]
    if tree is None:
        tree = cKDTree(points)
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (n,)).copy()
    if not np.all(np.isfinite(radius)) or np.any(radius <= 0):
        raise HeatcurvError("the ball radius must be finite and positive")
    if min_neighbors >= n:
        raise HeatcurvError(f"need more than {min_neighbors} points for {min_neighbors} neighbours, got {n}")
    lists = tree.query_ball_point(points, radius, workers=workers, return_sorted=True)
    counts = np.fromiter(map(len, lists), dtype=np.int64, count=n)
    flat = np.fromiter(chain.from_iterable(lists), dtype=np.int64, count=int(counts.sum()))
    del lists
    rows = np.repeat(np.arange(n), counts)
    keep = flat != rows  # drop the point itself
    rows, cols = rows[keep], flat[keep]
    counts = counts - 1

    augmented = counts < min_neighbors
    if augmented.any():
        sparse_ids = np.flatnonzero(augmented)
        _, nn = tree.query(points[sparse_ids], k=min_neighbors + 1, workers=workers)
        nn = nn[:, 1:]
        keep_rows = ~np.isin(rows, sparse_ids)
        rows = np.concatenate([rows[keep_rows], np.repeat(sparse_ids, min_neighbors)])
        cols = np.concatenate([cols[keep_rows], nn.reshape(-1)])
        order = np.lexsort((cols, rows))
        rows, cols = rows[order], cols[order]
        counts = np.bincount(rows, minlength=n)
        # radius of an augmented point: its farthest neighbour
        radius[sparse_ids] = np.maximum(
            radius[sparse_ids], np.linalg.norm(points[nn[:, -1]] - points[sparse_ids], axis=1)
        )

    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    distances = np.linalg.norm(points[cols] - points[rows], axis=1)
    return Neighbourhood(
        indptr=indptr,
        indices=cols.astype(_index_dtype(n)),
        distances=distances,
        radius=radius,
        augmented=augmented,
    )
