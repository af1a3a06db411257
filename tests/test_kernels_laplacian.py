"""The default Laplacian's compiled kernels (:mod:`heatcurv._kernels.laplacian`) against numpy references."""

import numpy as np
from scipy.spatial import cKDTree

from heatcurv._kernels import laplacian as kernels


def _csr(points: np.ndarray, k: int):
    """Each point's ``k`` nearest other points as CSR arrays, and random positive pair weights."""
    _, idx = cKDTree(points).query(points, k + 1)
    indices = idx[:, 1:].reshape(-1).astype(np.int64)
    indptr = np.arange(0, indices.size + 1, k, dtype=np.int64)
    weights = np.random.default_rng(1).uniform(0.1, 1.0, indices.size)
    return indptr, indices, weights


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_border_moments_match_numpy():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(300, 3))
    normals = _unit(rng.normal(size=(300, 3)))
    indptr, indices, weights = _csr(X, 12)
    moment, total = kernels.border_moments(X, indptr, indices, weights, normals)
    rows = np.repeat(np.arange(300), 12)
    d = (X[indices] - X[rows]) * weights[:, None]
    raw = np.add.reduceat(d, indptr[:-1], axis=0)
    expected = raw - np.sum(raw * normals, axis=1, keepdims=True) * normals
    np.testing.assert_allclose(moment, expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(total, np.add.reduceat(weights, indptr[:-1]), rtol=1e-12)
    # the moment lies in the tangent plane
    assert np.abs(np.sum(moment * normals, axis=1)).max() < 1e-12


def test_moment_weights_blend_and_fall_back_to_isotropic():
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(size=(400, 2)), np.zeros(400)])  # a flat square
    indptr, indices, weights = _csr(X, 16)
    rows = np.repeat(np.arange(400), 16)
    along = np.tile([1.0, 0.0, 0.0], (400, 1))
    beta = rng.uniform(0.0, 1.0, 400)
    beta[:50] = 0.0
    out = kernels.moment_weights(X, indptr, indices, weights, beta, along)
    d = X[indices] - X[rows]
    iso, dv = np.sum(d * d, axis=1), d[:, 0]
    # a row whose along-sum is at most half its isotropic sum keeps the isotropic calibration
    along_sum = np.add.reduceat(2.0 * weights * dv * dv, indptr[:-1])
    iso_sum = np.add.reduceat(weights * iso, indptr[:-1])
    b = np.where(along_sum > 0.5 * iso_sum, beta, 0.0)[rows]
    np.testing.assert_allclose(out, 0.25 * weights * ((1.0 - b) * iso + 2.0 * b * dv * dv), rtol=1e-12)
    assert np.all(out[: 50 * 16] == 0.25 * weights[: 50 * 16] * iso[: 50 * 16])


def test_voronoi_cells_of_a_lattice_are_its_cells():
    # a square lattice of spacing 0.1 in the plane z = 0: every interior cell is 0.1 x 0.1 and closed;
    # an edge cell, open, clipped half a spacing beyond its point is 0.1 x 0.1 too
    g = np.arange(12) * 0.1
    X = np.column_stack([a.ravel() for a in np.meshgrid(g, g)] + [np.zeros(144)])
    _, idx = cKDTree(X).query(X, 31)
    normals = np.tile([0.0, 0.0, 1.0], (144, 1))
    area, opened = kernels.voronoi_cells(X, idx[:, 1:].astype(np.int64), normals, np.full(144, 0.05))
    interior = (np.abs(X[:, :2] - 0.55) < 0.45).all(axis=1)
    corner = (np.abs(X[:, :2] - 0.55) > 0.5).all(axis=1)
    edge = ~interior & ~corner
    np.testing.assert_allclose(area[interior | edge], 0.01, rtol=1e-9)
    assert not opened[interior].any() and opened[corner].all()
    # a corner's cell opens diagonally: clipped on the diagonal, larger than a quarter cell's square
    assert np.all(area[corner] > 0.01)


def test_heat_method_gradient_and_divergence_match_numpy():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(300, 3))
    indptr, indices, weights = _csr(X, 12)
    rows = np.repeat(np.arange(300), 12)
    d = X[indices] - X[rows]
    second = kernels.pair_second_moments(X, indptr, indices, weights)
    expected = np.zeros((300, 3, 3))
    np.add.at(expected, rows, weights[:, None, None] * d[:, :, None] * d[:, None, :])
    np.testing.assert_allclose(second, expected, rtol=1e-12, atol=1e-12)

    inverse = rng.normal(size=(300, 3, 3))
    u = rng.normal(size=300)
    slope = np.zeros((300, 3))
    np.add.at(slope, rows, (weights * (u[indices] - u[rows]))[:, None] * d)
    np.testing.assert_allclose(kernels.tangent_gradient(X, indptr, indices, weights, inverse, u),
                               np.einsum("nij,nj->ni", inverse, slope), rtol=1e-12, atol=1e-12)

    field = rng.normal(size=(300, 3))
    divergence = -0.5 * np.bincount(rows, weights * np.sum((field[rows] + field[indices]) * d, axis=1), minlength=300)
    np.testing.assert_allclose(kernels.weak_divergence(X, indptr, indices, weights, field), divergence,
                               rtol=1e-12, atol=1e-12)

    normals = rng.normal(size=(300, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    heights = np.sum(normals[rows] * d, axis=1) ** 2 + np.sum(normals[indices] * d, axis=1) ** 2
    np.testing.assert_allclose(kernels.arc_over_chord(X, indptr, indices, normals),
                               1.0 + heights / (12.0 * np.sum(d * d, axis=1)), rtol=1e-12)
