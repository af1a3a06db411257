"""heatcurv._kernels.graph: the compiled spanning forest and components against SciPy's, entry for entry; kept pairs."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse import csgraph

from heatcurv._kernels import graph as graph_kernels
from heatcurv._kernels.graph import (
    connected_components,
    forest_parity,
    minimum_spanning_forest,
    pairs_between_kept,
    undirected_edges,
)


def scipy_forest(indptr, indices, cost):
    """The entries ``csgraph.minimum_spanning_tree`` keeps, as a mask over the CSR entries."""
    n = len(indptr) - 1
    marked = sp.csr_matrix((np.arange(1.0, len(cost) + 1), indices, indptr), shape=(n, n))
    tree = csgraph.minimum_spanning_tree(sp.csr_matrix((cost, indices, indptr), shape=(n, n)))
    # the same pattern as the input's: which entries survived, read off a copy that numbers them
    kept = np.zeros(len(cost), dtype=bool)
    rows = np.repeat(np.arange(n), np.diff(tree.indptr))
    kept[(marked[rows, tree.indices].A1 - 1).astype(np.int64)] = True
    return kept


def random_graph(n, k, seed, ties=False, islands=0):
    """``k`` random neighbours per vertex (no self-loops), CSR; ``islands`` vertices at the end have none."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n - islands):
        choice = rng.choice(n - islands - 1, size=min(k, n - islands - 1), replace=False)
        rows.append(np.where(choice >= i, choice + 1, choice))
    rows += [np.empty(0, dtype=np.int64)] * islands
    indptr = np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64)
    indices = np.concatenate(rows).astype(np.int32)
    cost = rng.random(len(indices)) + 0.1
    if ties:  # a few distinct values: the order of equal costs decides
        cost = np.round(cost, 1)
    return indptr, indices, cost


@pytest.mark.parametrize("ties", [False, True])
@pytest.mark.parametrize("n, k, islands", [(2, 1, 0), (50, 3, 0), (2000, 10, 0), (3000, 2, 40), (500, 1, 0)])
def test_same_entries_as_scipy(n, k, islands, ties):
    indptr, indices, cost = random_graph(n, k, seed=n + k, ties=ties, islands=islands)
    got = minimum_spanning_forest(indptr, indices, cost)
    assert np.array_equal(got, scipy_forest(indptr, indices, cost))


def test_both_directions_of_an_edge_the_cheaper_is_kept():
    # 0 -> 1 (cost 2) and 1 -> 0 (cost 1): one edge, the cheaper entry; equal costs: the earlier entry
    indptr, indices = np.array([0, 1, 2]), np.array([1, 0], dtype=np.int32)
    assert minimum_spanning_forest(indptr, indices, np.array([2.0, 1.0])).tolist() == [False, True]
    assert minimum_spanning_forest(indptr, indices, np.array([1.0, 1.0])).tolist() == [True, False]


def test_empty_graph_and_components():
    assert minimum_spanning_forest(np.zeros(4, dtype=np.int64), np.empty(0, dtype=np.int32), np.empty(0)).size == 0
    # two triangles: two edges each
    indptr = np.array([0, 2, 3, 4, 6, 7, 8])
    indices = np.array([1, 2, 2, 0, 4, 5, 5, 3], dtype=np.int32)
    cost = np.array([1.0, 3.0, 2.0, 5.0, 1.0, 3.0, 2.0, 5.0])
    got = minimum_spanning_forest(indptr, indices, cost)
    assert got.sum() == 4 and np.array_equal(got, scipy_forest(indptr, indices, cost))


@pytest.mark.parametrize("n, k, islands", [(1, 0, 1), (50, 1, 0), (3000, 1, 40), (3000, 2, 0), (2000, 10, 5)])
def test_components_labelled_as_scipy(n, k, islands):
    indptr, indices, cost = random_graph(n, k, seed=n + k, islands=islands) if k else (np.zeros(n + 1, np.int64),
                                                                                      np.empty(0, np.int32), None)
    kept = np.random.default_rng(n).random(len(indices)) < 0.7  # a subset of the entries
    for mask in (None, kept):
        weights = np.ones(len(indices)) if mask is None else mask.astype(float)
        graph = sp.csr_matrix((weights, indices.copy(), indptr.copy()), shape=(n, n))
        graph.eliminate_zeros()  # (in place: on copies of the arrays)
        want = csgraph.connected_components(graph, directed=False)
        got = connected_components(indptr, indices, mask)
        assert got[0] == want[0] and np.array_equal(got[1], want[1])


@pytest.mark.parametrize("share", [0.0, 0.01, 0.3, 1.0])
def test_pairs_between_kept_vertices_as_numpy_selects_them(share):
    indptr, indices, cost = random_graph(3000, 10, seed=4, islands=20)
    excluded = np.random.default_rng(5).random(3000) < share
    rows = np.repeat(np.arange(3000), np.diff(indptr))
    expected = np.flatnonzero(~excluded[rows] & ~excluded[indices])
    new_indptr, kept, lengths = pairs_between_kept(indptr, indices, cost, excluded)
    np.testing.assert_array_equal(kept, indices[expected])
    np.testing.assert_array_equal(lengths, cost[expected])
    assert kept.dtype == indices.dtype and lengths.dtype == np.float64
    np.testing.assert_array_equal(np.diff(new_indptr), np.bincount(rows[expected], minlength=3000))
    assert new_indptr[0] == 0 and np.all(np.diff(new_indptr)[excluded] == 0)


def test_forest_parity_is_the_flips_on_the_path_from_the_root():
    indptr, indices, cost = random_graph(3000, 6, seed=6, islands=30)
    n = 3000
    tree = csgraph.minimum_spanning_tree(sp.csr_matrix((cost, indices, indptr), shape=(n, n)))
    forest = (tree + tree.T).tocsr()
    rng = np.random.default_rng(7)
    points, normals = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    _, labels = csgraph.connected_components(forest, directed=False)
    roots = np.zeros(n, dtype=bool)
    roots[np.unique(labels, return_index=True)[1]] = True
    parity = forest_parity(forest.indptr, forest.indices, roots, points, normals)
    # reference: each tree's breadth-first order from its root, a node's flip read off its parent
    expected = np.zeros(n, dtype=bool)
    for root in np.flatnonzero(roots):
        order, parent = csgraph.breadth_first_order(forest, root, directed=False, return_predecessors=True)
        for v in order[1:]:
            u = parent[v]
            e = (points[v] - points[u]) / np.linalg.norm(points[v] - points[u])
            agreement = normals[u] @ normals[v] - (normals[u] @ e) * (normals[v] @ e)
            expected[v] = expected[u] ^ (agreement < 0)
    np.testing.assert_array_equal(parity, expected)
    assert parity.any() and not parity[roots].any()


@pytest.mark.parametrize("ties", [False, True])
@pytest.mark.parametrize("per_block", [1, 7, 1000])
def test_the_forest_is_the_same_whatever_the_scan_is_cut_into(monkeypatch, per_block, ties):
    # blocks of the edges scanned side by side, their choices merged: the same entries as one block and as SciPy's
    indptr, indices, cost = random_graph(3000, 6, seed=11, ties=ties, islands=25)
    one_block = minimum_spanning_forest(indptr, indices, cost)
    monkeypatch.setattr(graph_kernels, "MIN_EDGES_PER_BLOCK", per_block)
    monkeypatch.setattr(graph_kernels, "get_num_threads", lambda: 4)  # four blocks on any machine
    got = minimum_spanning_forest(indptr, indices, cost)
    assert np.array_equal(got, one_block) and np.array_equal(got, scipy_forest(indptr, indices, cost))


def test_undirected_edges_once_each_without_excluded_vertices():
    indptr, indices, cost = random_graph(2000, 5, seed=9, islands=10)
    n = 2000
    sym = sp.csr_matrix((cost, indices, indptr), shape=(n, n))
    sym = (sym + sym.T).tocsr()
    rng = np.random.default_rng(3)
    points, excluded = rng.normal(size=(n, 3)), rng.random(n) < 0.05
    i, j, entry, length = undirected_edges(sym.indptr, sym.indices, excluded, points)
    rows = np.repeat(np.arange(n), np.diff(sym.indptr))
    want = np.flatnonzero((rows < sym.indices) & ~excluded[rows] & ~excluded[sym.indices])
    np.testing.assert_array_equal(entry, want)
    np.testing.assert_array_equal(i, rows[want])
    np.testing.assert_array_equal(j, sym.indices[want])
    np.testing.assert_allclose(length, np.linalg.norm(points[j] - points[i], axis=1), rtol=1e-15)
