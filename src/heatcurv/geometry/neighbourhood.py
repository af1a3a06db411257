"""Ball neighbourhoods ``B_r(x_i) = {x_j : |xi - xj| <= r_i}`` as flat CSR arrays.

The paper (section 2) sums every operator over the ball of radius
``r = alpha h`` (``3.5 <= alpha <= 4.5``). The operator's neighbourhood
(:mod:`heatcurv.operators.operator`) is computed once and shared by the areas, the
Laplacian, the normals and their orientation, and the paper's principal fit;
the default estimator's chord fit queries its own, noise-adapted one (the
stage ``fit_neighbourhood``, block by block). Both are stored as CSR arrays:
the neighbours of point ``i`` are ``indices[indptr[i]:indptr[i+1]]`` at
distances ``distances[...]``. The point itself is not stored; stages that need
the diagonal (the area system) add it.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

from .._kernels.graph import pairs_between_kept
from ..errors import HeatcurvError

__all__ = [
    "Neighbourhood", "ball_neighbourhood", "knn_neighbourhood", "BLOCK_PAIRS", "QUERY_PAIRS", "rows_per_block",
    "block_ranges",
]

# The one block-size policy, in neighbour pairs. Every stage that streams over pairs
# sizes its blocks with rows_per_block() from one of these two budgets.

#: Pairs a streamed stage holds at once: a block of the default fit with its own
#: neighbourhood (about 1 KB per pair at its peak, so ~1 GB), the numpy temporaries of
#: ``Neighbourhood.blockwise``.
BLOCK_PAIRS = 1_000_000

#: Pairs one k-d tree query returns at once (scipy's int64 + float64 arrays, 16 bytes a
#: pair, ~200 MB, before they are narrowed): 200 000 points at the default 60 neighbours.
#: Smaller batches cost time (1M points, k = 60: 5.6 s at this size, 6.2 s at BLOCK_PAIRS).
QUERY_PAIRS = 12_000_000

#: Pairs per query expected in the first block of a ball query (later blocks use the
#: mean count found so far), sizing it to :data:`BLOCK_PAIRS`.
BALL_GUESS = 64


def rows_per_block(pairs_per_row: int, block_pairs: int | None = None) -> int:
    """Rows (points) per block when each row holds ``pairs_per_row`` pairs (at least 1).

    ``block_pairs`` defaults to :data:`BLOCK_PAIRS`, read at call time.
    """
    pairs = BLOCK_PAIRS if block_pairs is None else block_pairs
    return max(1, int(pairs) // max(int(pairs_per_row), 1))


def block_ranges(n_rows: int, rows: int):
    """Consecutive ``(lo, hi)`` ranges of ``rows`` rows covering ``range(n_rows)``."""
    for lo in range(0, n_rows, rows):
        yield lo, min(n_rows, lo + rows)


@dataclass(frozen=True)
class Neighbourhood:
    """Neighbour lists of a point cloud in CSR form.

    Attributes
    ----------
    indptr : ndarray, shape (n + 1,), int64
        Row pointers.
    indices : ndarray, shape (nnz,), int32 or int64
        Neighbour indices (int32 where they fit), ascending within each row
        for ball neighbourhoods, by distance for :func:`knn_neighbourhood`;
        the point itself excluded.
    distances : ndarray, shape (nnz,), float64
        ``|x_i - x_j|`` for each stored pair.
    radius : ndarray, shape (n,), float64
        Ball radius used for each point.
    augmented : ndarray, shape (n,), bool
        Points whose ball held fewer than ``min_neighbours`` points and were
        given their nearest neighbours instead (isolated points, sparse edges).
    by_distance : bool
        Whether each row is known to be sorted by distance, nearest first
        (:func:`knn_neighbourhood` rows are).
    """

    indptr: np.ndarray
    indices: np.ndarray
    distances: np.ndarray
    radius: np.ndarray
    augmented: np.ndarray
    by_distance: bool = False

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

    @staticmethod
    def concatenate(parts: list) -> Neighbourhood:
        """Stack the rows of several neighbourhoods (e.g. consecutive blocks of centres)."""
        if len(parts) == 1:
            return parts[0]
        offsets = np.cumsum([0] + [p.n_pairs for p in parts[:-1]])
        return Neighbourhood(
            indptr=np.concatenate([parts[0].indptr[:1]] + [p.indptr[1:] + o for p, o in zip(parts, offsets)]),
            indices=np.concatenate([p.indices for p in parts]),
            distances=np.concatenate([p.distances for p in parts]),
            radius=np.concatenate([p.radius for p in parts]),
            augmented=np.concatenate([p.augmented for p in parts]),
            by_distance=all(p.by_distance for p in parts),
        )

    def kth_distance(self, k: int) -> np.ndarray:
        """Distance of each row's ``k``-th nearest stored neighbour (its farthest if fewer; 0 if none), shape (n,)."""
        counts = self.counts
        if self.n_pairs == 0:
            return np.zeros(self.n_points)
        if not (self.by_distance or self._sorted_by_distance()):
            return np.where(counts > 0, self.nearest(k).radius, 0.0)
        last = self.indptr[:-1] + np.minimum(counts, k) - 1  # rows nearest first: no pairs are copied
        return np.where(counts > 0, self.distances[np.maximum(last, 0)], 0.0)

    def nearest(self, k: int) -> Neighbourhood:
        """Each row's ``k`` nearest stored neighbours (all of a shorter row), nearest first.

        ``radius`` becomes the distance of the farthest one kept.
        """
        counts = self.counts
        by_distance = self.by_distance or self._sorted_by_distance()
        if self.n_pairs == 0 or counts.max() <= k and by_distance:
            return self
        if counts.min() == counts.max() and by_distance:
            width = int(counts[0])
            idx = self.indices.reshape(-1, width)[:, :k]
            dist = self.distances.reshape(-1, width)[:, :k]
            new_counts = np.full(self.n_points, idx.shape[1])
            idx, dist = idx.reshape(-1), dist.reshape(-1)
        else:
            rows = self.rows
            order = np.lexsort((self.distances, rows))
            rank = np.arange(self.n_pairs) - self.indptr[rows[order]]
            keep = order[rank < k]
            idx, dist = self.indices[keep], self.distances[keep]
            new_counts = np.minimum(counts, k)
        indptr = np.zeros(self.n_points + 1, dtype=np.int64)
        np.cumsum(new_counts, out=indptr[1:])
        last = np.maximum(indptr[1:] - 1, 0)
        radius = np.where(new_counts > 0, dist[last] if dist.size else 0.0, self.radius)
        return Neighbourhood(
            indptr=indptr, indices=idx, distances=dist, radius=radius, augmented=self.augmented, by_distance=True
        )

    def spread(self, k: int) -> Neighbourhood:
        """``k`` neighbours per row: the ``k // 2`` nearest and the rest at evenly spaced ranks out to the farthest.

        A sparse graph that still reaches across the whole ball: the ``k``
        nearest alone can all lie on one scan line when a scanner samples
        densely along its lines and sparsely across them (a sphere scanned
        16x denser along 40 lines than across splits into 40 components of
        the 10-nearest graph, and stays one in this one). Rows with at
        most ``k`` neighbours are kept whole; the rows come out sorted by distance.
        """
        near = self if (self.by_distance or self._sorted_by_distance()) else self.nearest(self.counts.max())
        counts = near.counts
        if near.n_pairs == 0 or counts.max() <= k:
            return near
        h, m = k // 2, k - k // 2

        def picked(rank, c):
            # ranks < h, then m evenly spaced ranks over h .. c-1 (the last is c-1)
            far = np.maximum(c - 1 - h, 1)
            spaced = np.round(np.round((rank - h) * (m - 1) / far) * far / (m - 1)) + h == rank
            return (rank < h) | ((rank >= h) & spaced) | (c <= k)

        if counts.min() == counts.max():
            # one row length (kNN rows): the same ranks in every row, a column slice
            width = int(counts[0])
            ranks = np.flatnonzero(picked(np.arange(width), width))
            # (np.take: 4x faster than fancy indexing on a million rows)
            return Neighbourhood(
                indptr=np.arange(0, near.n_points * k + 1, k, dtype=np.int64),
                indices=np.take(near.indices.reshape(-1, width), ranks, axis=1).reshape(-1),
                distances=np.take(near.distances.reshape(-1, width), ranks, axis=1).reshape(-1),
                radius=near.radius, augmented=near.augmented, by_distance=True,
            )
        rows = near.rows
        keep = picked(np.arange(near.n_pairs) - near.indptr[rows], counts[rows])
        new_counts = np.bincount(rows[keep], minlength=near.n_points)
        indptr = np.zeros(near.n_points + 1, dtype=np.int64)
        np.cumsum(new_counts, out=indptr[1:])
        return Neighbourhood(
            indptr=indptr, indices=near.indices[keep], distances=near.distances[keep], radius=near.radius,
            augmented=near.augmented, by_distance=True,
        )

    def without(self, excluded: np.ndarray) -> Neighbourhood:
        """The pairs whose two points are both kept: rows of ``excluded`` points become empty.

        Parameters
        ----------
        excluded : ndarray, shape (n,), bool
            Points to cut out of the graph (e.g. outliers).
        """
        if not excluded.any():
            return self
        indptr, indices, distances = pairs_between_kept(self.indptr, self.indices, self.distances, excluded)
        return Neighbourhood(
            indptr=indptr.astype(self.indptr.dtype, copy=False), indices=indices, distances=distances,
            radius=self.radius, augmented=self.augmented, by_distance=self.by_distance,
        )

    def _sorted_by_distance(self) -> bool:
        """Whether the distances ascend within every row."""
        step = np.diff(self.distances)
        within = np.ones(step.shape[0], dtype=bool)
        within[self.indptr[1:-1][(self.indptr[1:-1] > 0) & (self.indptr[1:-1] < self.n_pairs)] - 1] = False
        return bool(np.all(step[within] >= 0))

    def row_blocks(self, max_pairs: int):
        """Split the rows into consecutive ranges of at most about ``max_pairs`` pairs.

        Yields
        ------
        (lo, hi) : tuple of int
            Row range; a single row with more pairs than ``max_pairs`` is its own block.
        """
        n, lo = self.n_points, 0
        while lo < n:
            hi = int(np.searchsorted(self.indptr, self.indptr[lo] + max_pairs, side="right")) - 1
            hi = min(max(hi, lo + 1), n)
            yield lo, hi
            lo = hi

    def rows_slice(self, lo: int, hi: int) -> Neighbourhood:
        """The neighbourhood of rows ``lo:hi`` (indices still refer to the whole cloud)."""
        a, b = self.indptr[lo], self.indptr[hi]
        return Neighbourhood(
            indptr=self.indptr[lo : hi + 1] - a,
            indices=self.indices[a:b],
            distances=self.distances[a:b],
            radius=self.radius[lo:hi],
            augmented=self.augmented[lo:hi],
            by_distance=self.by_distance,
        )

    def take_rows(self, rows: np.ndarray) -> Neighbourhood:
        """The neighbourhood of the given rows (e.g. a random subsample), in that order."""
        rows = np.asarray(rows, dtype=np.int64)
        counts = self.counts[rows]
        indptr = np.zeros(rows.shape[0] + 1, dtype=np.int64)
        np.cumsum(counts, out=indptr[1:])
        # position of every kept pair in the full arrays: its row's start plus its rank in the row
        pairs = np.repeat(self.indptr[rows], counts) + (np.arange(indptr[-1]) - np.repeat(indptr[:-1], counts))
        return Neighbourhood(
            indptr=indptr,
            indices=self.indices[pairs],
            distances=self.distances[pairs],
            radius=self.radius[rows],
            augmented=self.augmented[rows],
            by_distance=self.by_distance,
        )

    def blockwise(self, compute, max_pairs: int | None = None) -> np.ndarray:
        """Apply ``compute(lo, hi, block)`` to consecutive row blocks and stack the results.

        ``block`` is ``self.rows_slice(lo, hi)``; ``compute`` returns an array
        with ``hi - lo`` rows. Bounds the per-pair temporaries of numpy code
        to about ``max_pairs`` pairs (default :data:`BLOCK_PAIRS`).
        """
        max_pairs = BLOCK_PAIRS if max_pairs is None else max_pairs
        parts = [compute(lo, hi, self.rows_slice(lo, hi)) for lo, hi in self.row_blocks(max_pairs)]
        return np.concatenate(parts) if len(parts) != 1 else parts[0]

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
    min_neighbours: int = 6,
    workers: int = -1,
    queries: np.ndarray | None = None,
    source_index: np.ndarray | None = None,
) -> Neighbourhood:
    """All neighbours within ``radius`` of each query point, in CSR form.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points to search (the tree's points).
    radius : float or ndarray, shape (m,)
        Ball radius ``r_i = alpha h_i`` of each query; a scalar gives the
        symmetric neighbourhood of the paper's global spacing.
    tree : scipy.spatial.cKDTree, optional
        A tree already built on ``points``.
    min_neighbours : int, optional
        A query whose ball holds fewer neighbours gets its ``min_neighbours``
        nearest ones instead and is marked in ``augmented``; without it,
        isolated points would have no normal and no curvature.
    workers : int, optional
        Threads for the k-d tree queries.
    queries : ndarray, shape (m, 3), optional
        Centres of the balls (default: ``points`` themselves). A query that
        coincides with a point does not count itself as its neighbour.
    source_index : ndarray, shape (n,), optional
        Global index of each of ``points``: when ``points`` is a subset of a
        larger cloud (a coarser level), the returned ``indices`` are mapped
        through it.

    Returns
    -------
    Neighbourhood
        One row per query.
    """
    if tree is None:
        tree = cKDTree(points)
    if queries is None:
        queries = points
    n_src, m = points.shape[0], queries.shape[0]
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (m,)).copy()
    if not np.all(np.isfinite(radius)) or np.any(radius <= 0):
        raise HeatcurvError("the ball radius must be finite and positive")
    if min_neighbours >= n_src:
        raise HeatcurvError(f"need more than {min_neighbours} points for {min_neighbours} neighbours, got {n_src}")
    counts = np.empty(m, dtype=np.int64)
    cols_parts, dist_parts = [], []
    lo, rows_in_block = 0, rows_per_block(BALL_GUESS)
    while lo < m:
        # blocks of queries bound scipy's Python lists (about 40 bytes a pair) and the
        # coordinate differences; each block is sized by the mean count of the last
        hi = min(m, lo + rows_in_block)
        lists = tree.query_ball_point(queries[lo:hi], radius[lo:hi], workers=workers, return_sorted=True)
        found = np.fromiter(map(len, lists), dtype=np.int64, count=hi - lo)
        cols = np.fromiter(chain.from_iterable(lists), dtype=np.int64, count=int(found.sum()))
        del lists
        rows = np.repeat(np.arange(lo, hi), found)
        dist = np.linalg.norm(points[cols] - queries[rows], axis=1)
        keep = dist > 0  # the points are distinct: distance 0 is the query itself
        counts[lo:hi] = np.bincount(rows[keep] - lo, minlength=hi - lo)
        cols_parts.append(cols[keep].astype(_index_dtype(n_src)))
        dist_parts.append(dist[keep])
        rows_in_block = rows_per_block(int(np.ceil(found.mean())))
        lo = hi
    cols, dist = np.concatenate(cols_parts), np.concatenate(dist_parts)
    del cols_parts, dist_parts

    augmented = counts < min_neighbours
    if augmented.any():
        sparse_ids = np.flatnonzero(augmented)
        nd, nn = tree.query(queries[sparse_ids], k=min_neighbours + 1, workers=workers)
        # drop the query itself where it is one of the points, else the farthest
        self_hit = nd[:, 0] == 0
        nn = np.where(self_hit[:, None], nn[:, 1:], nn[:, :-1])
        nd = np.where(self_hit[:, None], nd[:, 1:], nd[:, :-1])
        rows = np.repeat(np.arange(m), counts)
        keep_rows = ~augmented[rows]
        rows = np.concatenate([rows[keep_rows], np.repeat(sparse_ids, min_neighbours)])
        cols = np.concatenate([cols[keep_rows], nn.reshape(-1).astype(cols.dtype)])
        dist = np.concatenate([dist[keep_rows], nd.reshape(-1)])
        order = np.lexsort((cols, rows))
        rows, cols, dist = rows[order], cols[order], dist[order]
        counts = np.bincount(rows, minlength=m)
        # radius of an augmented point: its farthest neighbour
        radius[sparse_ids] = np.maximum(radius[sparse_ids], nd[:, -1])

    indptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    if source_index is not None:
        cols = np.asarray(source_index)[cols]
        n_global = int(np.max(source_index)) + 1
    else:
        n_global = n_src
    return Neighbourhood(
        indptr=indptr,
        indices=cols.astype(_index_dtype(n_global)),
        distances=dist,
        radius=radius,
        augmented=augmented,
    )


def knn_neighbourhood(
    points: np.ndarray,
    k: int,
    tree: cKDTree | None = None,
    workers: int = -1,
    queries: np.ndarray | None = None,
    source_index: np.ndarray | None = None,
    block: int | None = None,
) -> Neighbourhood:
    """The ``k`` nearest other points of each query, as a ball neighbourhood of radius ``d_k``.

    The ball of radius ``R_i = d_k(i)`` (the distance to the ``k``-th nearest
    other point) holds exactly these ``k`` points, up to points tied at
    distance ``R_i``; every kernel of the default estimator is tapered to 0 at
    the ball's edge (:func:`heatcurv.operators.kernel.ball_taper`), so tied points carry
    no weight and the two neighbourhoods give the same results. One k-d tree
    query instead of a kNN query plus a ball query, and a fixed row length.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points to search (the tree's points).
    k : int
        Neighbours per query.
    tree : scipy.spatial.cKDTree, optional
        A tree already built on ``points``.
    workers : int, optional
        Threads for the k-d tree queries.
    queries : ndarray, shape (m, 3), optional
        Centres (default ``points``). A query that coincides with one of
        ``points`` does not count itself; other queries keep all ``k``.
    source_index : ndarray, shape (n,), optional
        Global index of each of ``points`` (a coarser level of a larger
        cloud); the returned ``indices`` are mapped through it.
    block : int, optional
        Queries per k-d tree call (default: :data:`QUERY_PAIRS` pairs' worth);
        bounds the temporaries.

    Returns
    -------
    Neighbourhood
        One row per query, ``k`` pairs each, nearest first; ``radius`` is ``d_k``.
    """
    if tree is None:
        tree = cKDTree(points)
    if queries is None:
        queries = points
    n_src, m = points.shape[0], queries.shape[0]
    k = int(k)
    if k < 1 or k >= n_src:
        raise HeatcurvError(f"need more than {k} points for {k} neighbours, got {n_src}")
    n_global = int(np.max(source_index)) + 1 if source_index is not None else n_src
    indices = np.empty((m, k), dtype=_index_dtype(n_global))
    distances = np.empty((m, k))
    for lo, hi in block_ranges(m, block or rows_per_block(k + 1, QUERY_PAIRS)):
        dist, idx = tree.query(queries[lo:hi], k=k + 1, workers=workers)
        # drop the query itself where it is one of the points (distance 0: the points
        # are distinct, so nothing else is at 0), else the (k+1)-th neighbour
        self_hit = dist[:, 0] == 0
        if self_hit.all():
            idx, dist = idx[:, 1:], dist[:, 1:]
        else:
            keep = np.where(self_hit[:, None], np.arange(1, k + 1), np.arange(k))
            idx, dist = np.take_along_axis(idx, keep, axis=1), np.take_along_axis(dist, keep, axis=1)
        distances[lo:hi] = dist
        indices[lo:hi] = idx if source_index is None else np.asarray(source_index)[idx]
    return Neighbourhood(
        indptr=np.arange(0, m * k + 1, k, dtype=np.int64),
        indices=indices.reshape(-1),
        distances=distances.reshape(-1),
        radius=distances[:, -1].copy(),
        augmented=np.zeros(m, dtype=bool),
        by_distance=True,
    )
