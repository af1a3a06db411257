"""Compiled graph kernels: minimum spanning forest and connected components of a CSR neighbour graph.

:func:`heatcurv.orient.orientation.orient` propagates one side of the normals over a
minimum spanning forest of the neighbour graph. :func:`minimum_spanning_forest`
finds it by Boruvka's algorithm: every round, each component takes its
cheapest edge to another component, and the edges left inside a component
are dropped. Edges are compared by ``(cost, position in the CSR arrays)``, a
strict total order, so the forest is unique: the one SciPy's
``csgraph.minimum_spanning_tree`` (Kruskal's algorithm over the costs sorted
stably, i.e. equal costs in CSR order) returns, position for position.
Measured on a million points (10 edges each): 3.9 s in SciPy, of which 2 s
sorting the costs; Boruvka sorts nothing.

:func:`merged_components` (the patches of :mod:`heatcurv.orient.enclosure`) joins
the components of some edges, then lets every component still smaller than a
size grow across the other edges, in one pass over them.

:func:`forest_parity` carries one side of the normals from each root over a
forest by a depth-first walk.

:func:`pairs_between_kept` drops the entries that touch excluded vertices (the
outliers cut out of the orientation graph) and gathers the rest in one pass.

:func:`connected_components` (the outliers' mutual-neighbour graph) joins the
edges' ends in a union-find and numbers the components as SciPy's
``csgraph.connected_components`` does, in the order of their first vertex,
without the symmetric copy of the graph SciPy builds.

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import as_floats, as_indices, as_pointers

__all__ = [
    "minimum_spanning_forest", "connected_components", "merged_components", "pairs_between_kept", "forest_parity",
]


def minimum_spanning_forest(indptr, indices, cost) -> np.ndarray:
    """The edges of the minimum spanning forest of an undirected CSR graph, as a mask over its entries.

    Parameters
    ----------
    indptr, indices : ndarray
        CSR graph of ``n = len(indptr) - 1`` vertices: entry ``p`` of row
        ``i`` is the undirected edge ``{i, indices[p]}`` (both directions may be
        stored, as two edges).
    cost : ndarray, shape (nnz,)
        Edge costs, finite and positive (as csgraph, which reads a zero as no edge).

    Returns
    -------
    ndarray, shape (nnz,), bool
        Whether each entry is an edge of the forest: the entries
        ``scipy.sparse.csgraph.minimum_spanning_tree`` keeps, ties between
        equal costs going to the earlier entry as in its stable sort.
    """
    indptr = as_pointers(indptr)
    n = indptr.shape[0] - 1
    cost = as_floats(cost)
    in_tree = np.zeros(cost.shape[0], dtype=np.bool_)
    _boruvka(n, indptr, as_indices(indices, n), cost, in_tree)
    return in_tree


@njit(cache=True, nogil=True, inline="always")
def _root(parent, v):
    """The root of ``v`` in the union-find forest ``parent``, halving the path on the way."""
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


@njit(cache=True, nogil=True, inline="always")
def _before(cost, e, f):
    """Whether edge ``e`` comes before edge ``f`` (``f`` may be -1, no edge): by cost, then position."""
    return f < 0 or cost[e] < cost[f] or (cost[e] == cost[f] and e < f)


@njit(cache=True, nogil=True)
def _boruvka(n, indptr, indices, cost, in_tree):
    m = indices.shape[0]
    source = np.empty(m, dtype=indices.dtype)
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            source[p] = i
    # the edges between different components (self-loops and zero costs are no edges)
    live = np.empty(m, dtype=np.int64)
    count = 0
    for p in range(m):
        if source[p] != indices[p] and cost[p] != 0.0:
            live[count] = p
            count += 1
    component = np.arange(n)  # each vertex's component: a union-find root, refreshed every round
    parent = np.arange(n)
    cheapest = np.full(n, -1, dtype=np.int64)
    while count > 0:
        # each component's cheapest edge to another component
        for t in range(count):
            e = live[t]
            a, b = component[source[e]], component[indices[e]]
            if _before(cost, e, cheapest[a]):
                cheapest[a] = e
            if _before(cost, e, cheapest[b]):
                cheapest[b] = e
        # join along them: with a strict order they form a forest (an edge two components chose is joined once)
        for c in range(n):
            e = cheapest[c]
            if e < 0:
                continue
            cheapest[c] = -1
            a, b = _root(parent, source[e]), _root(parent, indices[e])
            if a != b:
                parent[a] = b
                in_tree[e] = True
        for v in range(n):
            component[v] = _root(parent, v)
        # drop the edges now inside a component
        kept = 0
        for t in range(count):
            e = live[t]
            if component[source[e]] != component[indices[e]]:
                live[kept] = e
                kept += 1
        count = kept


def connected_components(indptr, indices, kept=None):
    """Connected components of an undirected CSR graph, labelled as ``scipy.sparse.csgraph.connected_components``.

    Parameters
    ----------
    indptr, indices : ndarray
        CSR graph of ``n = len(indptr) - 1`` vertices; entry ``p`` of row
        ``i`` is the undirected edge ``{i, indices[p]}``.
    kept : ndarray, shape (nnz,), bool, optional
        The entries that are edges (default: all).

    Returns
    -------
    n_components : int
    labels : ndarray, shape (n,), int64
        Component of each vertex, numbered ``0, 1, ...`` in the order of each
        component's first vertex (SciPy's numbering for undirected graphs).
    """
    indptr = as_pointers(indptr)
    n = indptr.shape[0] - 1
    indices = as_indices(indices, n)
    kept = np.ones(indices.shape[0], dtype=np.bool_) if kept is None else np.ascontiguousarray(kept, dtype=np.bool_)
    labels = np.empty(n, dtype=np.int64)
    count = _components(n, indptr, indices, kept, labels)
    return int(count), labels


@njit(cache=True, nogil=True)
def _components(n, indptr, indices, kept, labels):
    parent = np.arange(n)
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            if kept[p]:
                a, b = _root(parent, i), _root(parent, indices[p])
                if a != b:  # the larger root under the smaller: every root is its component's first vertex
                    if a < b:
                        parent[b] = a
                    else:
                        parent[a] = b
    count = 0
    for v in range(n):  # roots come first in their component: label them in order, then the rest after them
        root = _root(parent, v)
        if root == v:
            labels[v] = count
            count += 1
        else:
            labels[v] = labels[root]
    return count


def merged_components(n: int, i, j, joined, mergeable, min_size: int) -> np.ndarray:
    """Components of the ``joined`` edges, the small ones then merged across ``mergeable`` edges, shape (n,).

    Parameters
    ----------
    n : int
        Vertices.
    i, j : ndarray, shape (m,), int
        The edges' ends.
    joined, mergeable : ndarray, shape (m,), bool
        Edges that join their ends outright; edges that join them only while
        one of the two components has fewer than ``min_size`` vertices (taken
        in order, one pass).
    min_size : int

    Returns
    -------
    ndarray, shape (n,), int64
        Component of each vertex, numbered ``0, 1, ...`` in the order of each
        component's first vertex.
    """
    i = np.ascontiguousarray(i, dtype=np.int64)
    j = np.ascontiguousarray(j, dtype=np.int64)
    labels = np.empty(int(n), dtype=np.int64)
    _merged(int(n), i, j, np.ascontiguousarray(joined, dtype=np.bool_), np.ascontiguousarray(mergeable, dtype=np.bool_),
            int(min_size), labels)
    return labels


@njit(cache=True, nogil=True)
def _merged(n, i, j, joined, mergeable, min_size, labels):
    parent = np.arange(n)
    size = np.ones(n, dtype=np.int64)
    for e in range(i.shape[0]):
        if joined[e]:
            a, b = _root(parent, i[e]), _root(parent, j[e])
            if a != b:
                parent[b] = a
                size[a] += size[b]
    for e in range(i.shape[0]):
        if mergeable[e]:
            a, b = _root(parent, i[e]), _root(parent, j[e])
            if a != b and (size[a] < min_size or size[b] < min_size):
                parent[b] = a
                size[a] += size[b]
    first = np.full(n, -1, dtype=np.int64)
    count = 0
    for v in range(n):
        root = _root(parent, v)
        if first[root] < 0:
            first[root] = count
            count += 1
        labels[v] = first[root]


def pairs_between_kept(indptr, indices, distances, excluded) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The entries of a CSR graph whose two ends are both kept, as a new CSR graph.

    Parameters
    ----------
    indptr, indices, distances : ndarray
        CSR graph of ``n = len(indptr) - 1`` vertices and its entries' lengths.
    excluded : ndarray, shape (n,), bool
        Vertices whose rows and whose appearances in other rows are dropped.

    Returns
    -------
    indptr : ndarray, shape (n + 1,), int64
        Row pointers of the kept entries (excluded rows empty).
    indices : ndarray, shape (m,)
        The kept entries, in order, in the dtype of ``indices``.
    distances : ndarray, shape (m,), float64
        Their lengths.
    """
    indptr = as_pointers(indptr)
    n = indptr.shape[0] - 1
    excluded = np.ascontiguousarray(excluded, dtype=np.bool_)
    source = as_indices(indices, n)
    new_indptr = np.zeros(n + 1, dtype=np.int64)
    kept = np.empty(indptr[-1], dtype=source.dtype)
    lengths = np.empty(indptr[-1], dtype=np.float64)
    m = _kept_pairs(n, indptr, source, as_floats(distances), excluded, new_indptr, kept, lengths)
    # views: the dropped entries' tails stay allocated, cheaper than a copy's fresh pages
    return new_indptr, kept[:m].astype(np.asarray(indices).dtype, copy=False), lengths[:m]


@njit(cache=True, nogil=True)
def _kept_pairs(n, indptr, indices, distances, excluded, new_indptr, kept, lengths):
    m = 0
    for i in range(n):
        if not excluded[i]:
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                if not excluded[j]:
                    kept[m] = j
                    lengths[m] = distances[p]
                    m += 1
        new_indptr[i + 1] = m
    return m


def forest_parity(indptr, indices, roots, points, normals) -> np.ndarray:
    """Whether each normal must flip to agree with its tree's root, walking a spanning forest, shape (n,), bool.

    Along a forest edge ``{i, j}`` the side flips when the normals disagree,
    ``s_ij = n_i . n_j - (n_i . e)(n_j . e) < 0`` (``e`` the unit edge; ``s_ij``
    is symmetric), so a node's parity is that of the flips on its path from the
    root, which in a forest is unique.

    Parameters
    ----------
    indptr, indices : ndarray
        The forest as a symmetric CSR graph (each edge stored both ways).
    roots : ndarray, shape (n,), bool
        One vertex of every tree (a tree without one keeps parity False).
    points, normals : ndarray, shape (n, 3)

    Returns
    -------
    ndarray, shape (n,), bool
    """
    indptr = as_pointers(indptr)
    n = indptr.shape[0] - 1
    parity = np.zeros(n, dtype=np.bool_)
    _walk(n, indptr, as_indices(indices, n), np.ascontiguousarray(roots, dtype=np.bool_), as_floats(points),
          as_floats(normals), parity)
    return parity


@njit(cache=True, nogil=True)
def _walk(n, indptr, indices, roots, points, normals, parity):
    seen = np.zeros(n, dtype=np.bool_)
    stack = np.empty(n, dtype=np.int64)
    for r in range(n):
        if not roots[r] or seen[r]:
            continue
        seen[r] = True
        top = 0
        stack[0] = r
        while top >= 0:
            u = stack[top]
            top -= 1
            for p in range(indptr[u], indptr[u + 1]):
                v = indices[p]
                if seen[v]:
                    continue
                seen[v] = True
                e0 = points[v, 0] - points[u, 0]
                e1 = points[v, 1] - points[u, 1]
                e2 = points[v, 2] - points[u, 2]
                length = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                dot = normals[u, 0] * normals[v, 0] + normals[u, 1] * normals[v, 1] + normals[u, 2] * normals[v, 2]
                if length > 0.0:
                    along_u = (normals[u, 0] * e0 + normals[u, 1] * e1 + normals[u, 2] * e2) / length
                    along_v = (normals[v, 0] * e0 + normals[v, 1] * e1 + normals[v, 2] * e2) / length
                    dot -= along_u * along_v
                parity[v] = parity[u] ^ (dot < 0.0)
                top += 1
                stack[top] = v
