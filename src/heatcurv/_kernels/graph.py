"""Compiled graph kernels: minimum spanning forest and connected components of a CSR neighbour graph.

:func:`heatcurv.orient.orientation.orient` propagates one side of the normals over a
minimum spanning forest of the neighbour graph. :func:`minimum_spanning_forest`
finds it by Boruvka's algorithm: every round, each component takes its
cheapest edge to another component, the components are contracted and the
edges left inside one are dropped; the scan for the cheapest edges runs on
the worker threads. Edges are compared by ``(cost, position in the CSR arrays)``, a
strict total order, so the forest is unique: the one SciPy's
``csgraph.minimum_spanning_tree`` (Kruskal's algorithm over the costs sorted
stably, i.e. equal costs in CSR order) returns, position for position.
Measured on a million points (10 edges each): 3.9 s in SciPy, of which 2 s
sorting the costs; Boruvka sorts nothing.

:func:`merged_components` (the patches of :mod:`heatcurv.orient.enclosure`) joins
the components of some edges, then lets every component still smaller than a
size grow across the other edges, in one pass over them.

:func:`undirected_edges` lists a symmetric graph's edges once each, with their lengths.

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
from numba import get_num_threads, njit

from . import as_floats, as_indices, as_pointers, parallel_items

__all__ = [
    "minimum_spanning_forest", "connected_components", "merged_components", "pairs_between_kept", "forest_parity",
    "undirected_edges",
]

#: Fewest live edges a block of :func:`minimum_spanning_forest`'s scan holds (a smaller graph is one block).
MIN_EDGES_PER_BLOCK = 65536


def minimum_spanning_forest(indptr, indices, cost) -> np.ndarray:
    """The edges of the minimum spanning forest of an undirected CSR graph, as a mask over its entries.

    Boruvka's algorithm on a contracted graph: every round, each component
    takes its cheapest edge to another component, the chosen edges join
    components, and the edges left are relabelled by their ends' new
    components, those now inside one dropped. The components shrink at
    least twofold a round, so a round costs the edges still alive plus the
    components left. The scan for the cheapest edges runs on blocks of the
    edges side by side (:func:`heatcurv._kernels.parallel_items`), each block
    with its own cheapest edge per component, and the blocks' choices are
    merged in one serial pass: the strict order of the edges makes the result
    the same for any number of blocks.

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
    indices = as_indices(indices, n)
    m = indices.shape[0]
    in_tree = np.zeros(m, dtype=np.bool_)
    # the live edges (no self-loops, no zero costs): their entries and their ends' components, at first the vertices
    dtype = np.int32 if m < 2**31 else np.int64
    end_a = np.repeat(np.arange(n, dtype=dtype), np.diff(indptr))
    live = (end_a != indices) & (cost != 0.0)
    if live.all():
        entry, end_b = np.arange(m, dtype=dtype), indices.astype(dtype)
    else:
        entry = np.flatnonzero(live).astype(dtype)
        end_a, end_b = end_a[entry], indices[entry].astype(dtype)
    count = entry.shape[0]
    blocks = max(1, min(get_num_threads(), count // MIN_EDGES_PER_BLOCK))
    bounds = np.linspace(0, count, blocks + 1).astype(np.int64)
    first, stop = bounds[:-1].copy(), bounds[1:].copy()  # each block's live edges: first .. stop - 1
    cheapest = np.full((blocks, n), -1, dtype=np.int64)  # per block and component: a position among the live edges
    parent, label = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    components, items = n, list(range(blocks))
    while (stop - first).sum() > 0:
        parallel_items(lambda k: _cheapest_edges(first[k], stop[k], entry, end_a, end_b, cost, cheapest[k]), items)
        components = _join(components, cheapest, entry, end_a, end_b, cost, parent, label, in_tree)
        stop[:] = parallel_items(lambda k: _contract(first[k], stop[k], entry, end_a, end_b, label), items)
    return in_tree


@njit(cache=True, nogil=True, inline="always")
def _root(parent, v):
    """The root of ``v`` in the union-find forest ``parent``, halving the path on the way."""
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


@njit(cache=True, nogil=True, inline="always")
def _lighter(cost, entry, t, s):
    """Whether live edge ``t`` comes before live edge ``s`` (``s`` may be -1, no edge): by cost, then entry."""
    if s < 0:
        return True
    e, f = entry[t], entry[s]
    return cost[e] < cost[f] or (cost[e] == cost[f] and e < f)


@njit(cache=True, nogil=True)
def _cheapest_edges(first, stop, entry, end_a, end_b, cost, cheapest):
    """Each component's cheapest edge among the live edges ``first .. stop - 1``, into ``cheapest``."""
    for t in range(first, stop):
        if _lighter(cost, entry, t, cheapest[end_a[t]]):
            cheapest[end_a[t]] = t
        if _lighter(cost, entry, t, cheapest[end_b[t]]):
            cheapest[end_b[t]] = t


@njit(cache=True, nogil=True)
def _join(components, cheapest, entry, end_a, end_b, cost, parent, label, in_tree):
    """Join the components along their cheapest edges (the blocks' choices merged, then reset); number the new ones.

    With a strict order the chosen edges form a forest (an edge two components
    chose is joined once). ``label[c]`` is the new component of component
    ``c``; returns their number.
    """
    for c in range(components):
        parent[c] = c
    for c in range(components):
        t = -1
        for k in range(cheapest.shape[0]):
            s = cheapest[k, c]
            if s >= 0:
                cheapest[k, c] = -1
                if _lighter(cost, entry, s, t):
                    t = s
        if t >= 0:
            a, b = _root(parent, end_a[t]), _root(parent, end_b[t])
            if a != b:
                parent[a] = b
                in_tree[entry[t]] = True
    count = 0
    for c in range(components):
        if parent[c] == c:
            label[c] = count
            count += 1
    for c in range(components):
        label[c] = label[_root(parent, c)]
    return count


@njit(cache=True, nogil=True)
def _contract(first, stop, entry, end_a, end_b, label):
    """Relabel the live edges ``first ..`` by their ends' new components, dropping those inside one; the new stop."""
    kept = first
    for t in range(first, stop):
        a, b = label[end_a[t]], label[end_b[t]]
        if a != b:
            entry[kept], end_a[kept], end_b[kept] = entry[t], a, b
            kept += 1
    return kept


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


def undirected_edges(indptr, indices, excluded, points):
    """The edges ``{i, j}`` of a symmetric CSR graph once each (``i < j``), without excluded vertices.

    Parameters
    ----------
    indptr, indices : ndarray
        Symmetric CSR graph of ``n = len(indptr) - 1`` vertices.
    excluded : ndarray, shape (n,), bool
        Vertices whose edges are left out.
    points : ndarray, shape (n, 3)

    Returns
    -------
    i, j : ndarray, shape (e,), int64
        The edges' ends, ``i < j``, in CSR order.
    entry : ndarray, shape (e,), int64
        The position of each edge's entry ``(i, j)`` in the CSR arrays.
    length : ndarray, shape (e,), float64
        ``|points[j] - points[i]|``.
    """
    indptr = as_pointers(indptr)
    n = indptr.shape[0] - 1
    m = indptr[-1]
    i, j, entry = np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64)
    length = np.empty(m, dtype=np.float64)
    e = _upper_edges(n, indptr, as_indices(indices, n), np.ascontiguousarray(excluded, dtype=np.bool_),
                     as_floats(points), i, j, entry, length)
    return i[:e], j[:e], entry[:e], length[:e]


@njit(cache=True, nogil=True)
def _upper_edges(n, indptr, indices, excluded, points, i, j, entry, length):
    e = 0
    for a in range(n):
        if excluded[a]:
            continue
        for p in range(indptr[a], indptr[a + 1]):
            b = indices[p]
            if a < b and not excluded[b]:
                i[e], j[e], entry[e] = a, b, p
                d0, d1, d2 = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
                length[e] = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                e += 1
    return e


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
