"""Compiled winding-number kernel: the generalised winding numbers of an oriented cloud at query points.

A point ``x_j`` with area ``A_j`` and unit normal ``n_j`` is a small dipole;
its solid angle seen from ``q``, over ``4 pi``, is

``w_j(q) = A_j n_j . (x_j - q) / (4 pi |x_j - q|^3)``

(Barill et al. 2018, "Fast winding numbers for soups and clouds", eq. 8).
Summed over a closed, outward-oriented surface it is about 1 inside and 0
outside. :func:`winding_numbers` sums it per label, so that one pass gives
the field of every group of points (every patch of
:mod:`heatcurv.orient.enclosure`) at once: exact sums, ``O(queries x sources)``,
which :mod:`heatcurv.orient.enclosure` keeps bounded by its number of sources.

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, parallel_rows

__all__ = ["winding_numbers", "clipped_dipole_terms"]


def winding_numbers(queries, sources, dipoles, labels, n_labels: int) -> np.ndarray:
    """Winding numbers of labelled dipoles at the query points, one column per label.

    Parameters
    ----------
    queries : ndarray, shape (q, 3)
    sources : ndarray, shape (m, 3)
        The dipoles' positions (no query may coincide with one).
    dipoles : ndarray, shape (m, 3)
        Area times unit normal of each source.
    labels : ndarray, shape (m,), int
        The column each source adds to, ``0 <= label < n_labels``; a negative
        label leaves the source out.
    n_labels : int

    Returns
    -------
    ndarray, shape (q, n_labels)
        ``W[a, r] = sum_{j: labels[j] = r} d_j . (x_j - q_a) / (4 pi |x_j - q_a|^3)``, each term
        clipped to what a flat disc of the source's area ``|d_j|`` subtends on its axis at that
        distance, ``(1 - r / sqrt(r^2 + |d_j| / pi)) / 2``: a point sampled by noise next to a
        query counts as much as a piece of surface can, not without bound.
    """
    labels = np.asarray(labels, dtype=np.int64)
    kept = np.flatnonzero(labels >= 0)
    order = kept[np.argsort(labels[kept], kind="stable")]  # each label's sources in one run
    starts = np.searchsorted(labels[order], np.arange(int(n_labels) + 1)).astype(np.int64)
    out = np.zeros((len(queries), int(n_labels)))
    dipoles = as_floats(dipoles[order])
    disc2 = np.einsum("ij,ij->i", dipoles, dipoles) ** 0.5 / np.pi  # squared radius of a disc of the source's area
    parallel_rows(_winding_rows, out.shape[0], as_floats(queries), as_floats(sources[order]), dipoles, disc2, starts,
                  out)
    return out


def clipped_dipole_terms(offsets: np.ndarray, dipoles: np.ndarray) -> np.ndarray:
    """The terms :func:`winding_numbers` adds, for given source-minus-query offsets, shape (k,).

    Parameters
    ----------
    offsets : ndarray, shape (k, 3)
        ``x_j - q`` for each pair.
    dipoles : ndarray, shape (k, 3)
    """
    d2 = np.einsum("ij,ij->i", offsets, offsets)
    term = np.einsum("ij,ij->i", offsets, dipoles) / (d2 * np.sqrt(d2))
    bound = 2.0 * np.pi * (1.0 - np.sqrt(d2 / (d2 + np.linalg.norm(dipoles, axis=1) / np.pi)))
    return np.clip(term, -bound, bound) / (4.0 * np.pi)


@njit(**ROW_CORE, fastmath=True)
def _winding_rows(row0, row1, queries, sources, dipoles, disc2, starts, out):
    scale = 1.0 / (4.0 * np.pi)
    for a in range(row0, row1):
        qx, qy, qz = queries[a, 0], queries[a, 1], queries[a, 2]
        for r in range(starts.shape[0] - 1):
            total = 0.0
            for j in range(starts[r], starts[r + 1]):
                dx, dy, dz = sources[j, 0] - qx, sources[j, 1] - qy, sources[j, 2] - qz
                d2 = dx * dx + dy * dy + dz * dz
                term = (dx * dipoles[j, 0] + dy * dipoles[j, 1] + dz * dipoles[j, 2]) / (d2 * np.sqrt(d2))
                # no more than the source's disc subtends on its axis at this distance
                bound = 2.0 * np.pi * (1.0 - np.sqrt(d2 / (d2 + disc2[j])))
                total += min(max(term, -bound), bound)
            out[a, r] = scale * total
