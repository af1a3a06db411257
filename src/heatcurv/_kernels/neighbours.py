"""Compiled kernel of a tiled run's stored neighbourhoods (:mod:`heatcurv.tiles.neighbours`).

* :func:`stored_neighbours`: each distinct point's ``k`` nearest, read from
  lists of scratch positions and mapped to the rows of the points a tile
  read, with their distances recomputed as the k-d tree computes them; rows
  with a position the tile did not read are left to query.

Arrays in, arrays out: this module imports nothing from heatcurv but the
kernel helpers of :mod:`heatcurv._kernels`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, parallel_rows

__all__ = ["stored_neighbours"]


def stored_neighbours(points, first, lists, offsets, base, lookup, index_dtype):
    """The stored ``k`` nearest of every distinct point, as tile rows, and their distances.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        The tile's distinct points (the operator's coordinates).
    first : ndarray, shape (n,), int64
        The tile row (of the points read) of each distinct point.
    lists : ndarray, shape (m, k), int32 or int64
        Per tile row, the scratch positions of its ``k`` nearest, nearest
        first; a row starting with -1 is not stored.
    offsets : ndarray, shape (t + 1,), int64
        Where each tile's points start in the scratch files.
    base : ndarray, shape (t,), int64
        Where each tile's slice starts in ``lookup``; -1 for tiles not read.
    lookup : ndarray, int32 or int64
        Per scratch position of the tiles read (their slices end to end), its
        distinct point, -1 if not read.
    index_dtype : numpy dtype
        Of the returned indices.

    Returns
    -------
    indices : ndarray, shape (n, k)
        Distinct-point indices of each row's ``k`` nearest.
    distances : ndarray, shape (n, k)
        ``sqrt((dx^2 + dy^2) + dz^2)``, the k-d tree's sum in its order.
    known : ndarray, shape (n,), bool
        Rows read back; the others (``indices`` and ``distances`` undefined)
        must be queried.
    """
    n, k = points.shape[0], lists.shape[1]
    indices = np.empty((n, k), dtype=index_dtype)
    distances = np.empty((n, k))
    known = np.empty(n, dtype=np.bool_)
    parallel_rows(_stored_neighbours, n, as_floats(points), np.ascontiguousarray(first, dtype=np.int64),
                  np.ascontiguousarray(lists), np.ascontiguousarray(offsets, dtype=np.int64),
                  np.ascontiguousarray(base, dtype=np.int64), np.ascontiguousarray(lookup), indices, distances,
                  known)
    return indices, distances, known


@njit(**ROW_CORE)
def _stored_neighbours(row0, row1, points, first, lists, offsets, base, lookup, indices, distances, known):
    n_tiles = offsets.shape[0] - 1
    k = lists.shape[1]
    for i in range(row0, row1):
        r = first[i]
        ok = True
        for j in range(k):
            p = lists[r, j]
            if p < 0:
                ok = False
                break
            # the tile holding scratch position p (offsets ascending)
            lo, hi = 0, n_tiles
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if offsets[mid] <= p:
                    lo = mid
                else:
                    hi = mid
            if base[lo] < 0:
                ok = False
                break
            e = lookup[base[lo] + p - offsets[lo]]
            if e < 0:
                ok = False
                break
            indices[i, j] = e
            s = 0.0
            for a in range(3):
                t = points[e, a] - points[i, a]
                s += t * t
            distances[i, j] = np.sqrt(s)
        known[i] = ok
