"""numpy references of :mod:`heatcurv._kernels.segment`, function by function.

Same arguments, same returns, vectorised over all pairs at once (the former
numpy backend, which ran these formulas on blocks of rows; a row's sum does not
depend on the blocking). They differ from the kernels only in the order the
floating-point terms are summed, and in the eigensolver (LAPACK's ``eigh``
here, a 3 x 3 Jacobi iteration there). Each is written from the formula its
kernel documents and imports nothing from heatcurv: the flat-top taper too is
written again here from its definition (:func:`heatcurv.operators.kernel.flat_top`: 1 up to
``start``, a raised cosine down to 0 at ``u = 1``, 0 beyond).
"""

import numpy as np

__all__ = [
    "orientation_costs",
    "tapered_heat_weights",
    "taper_sums",
    "weighted_covariances",
    "smallest_eigenvectors",
    "kappa_normal_sums",
    "centroid_offsets",
]


def _rows(indptr):
    """The row (centre) of every pair."""
    return np.repeat(np.arange(indptr.shape[0] - 1), np.diff(indptr))


def _segment_sum(indptr, values):
    """Per-row sums of per-pair ``values`` (shape ``(nnz,)`` or ``(nnz, k)``), 0 for empty rows."""
    out = np.zeros((indptr.shape[0] - 1,) + values.shape[1:])
    nonempty = np.diff(indptr) > 0
    if values.shape[0]:
        out[nonempty] = np.add.reduceat(values, indptr[:-1][nonempty], axis=0)
    return out


def _flat_top(u, start):
    """1 for ``u <= start``, ``(1 + cos(pi (u - start) / (1 - start))) / 2`` up to ``u = 1``, 0 from there on."""
    fall = 0.5 * (1.0 + np.cos(np.pi * (u - start) / (1.0 - start)))
    return np.select([u <= start, u < 1.0], [1.0, fall], 0.0)


def _taper(indptr, distances, radius, start):
    """``flat_top(|xi - xj| / R_i)`` of every pair."""
    return _flat_top(distances / radius[_rows(indptr)], start)


def orientation_costs(points, normals, indptr, indices, distances, radius):
    """``1 - |n_i . n_j - (n_i . e)(n_j . e)| + max(|n_i . e|, |n_j . e|) + 1e-3 |xi - xj| / R_i + 1e-12``."""
    rows = _rows(indptr)
    edge = points[indices] - points[rows]
    edge = np.divide(edge, distances[:, None], out=np.zeros_like(edge), where=distances[:, None] > 0)
    ti = np.einsum("ij,ij->i", normals[rows], edge)
    tj = np.einsum("ij,ij->i", normals[indices], edge)
    align = np.abs(np.einsum("ij,ij->i", normals[rows], normals[indices]) - ti * tj)
    return (1.0 - align) + np.maximum(np.abs(ti), np.abs(tj)) + 1e-3 * distances / radius[rows] + 1e-12


def tapered_heat_weights(indptr, indices, distances, radius, inv_h2, areas, start):
    """``exp(-|xi - xj|^2 inv_h2[i]) flat_top(|xi - xj| / R_i) A_j`` per pair."""
    rows = _rows(indptr)
    return np.exp(-(distances**2) * inv_h2[rows]) * _taper(indptr, distances, radius, start) * areas[indices]


def taper_sums(indptr, distances, radius, start):
    """``sum_j flat_top(|xi - xj| / R_i)`` per point."""
    return _segment_sum(indptr, _taper(indptr, distances, radius, start))


def weighted_covariances(points, indptr, indices, distances, radius, start, use_taper):
    """Covariance of each neighbourhood and its centre (weight 1), shape (n, 3, 3)."""
    w = _taper(indptr, distances, radius, start) if use_taper else np.ones(indices.shape[0])
    n = indptr.shape[0] - 1
    centres = points[:n]
    rows = _rows(indptr)
    total = _segment_sum(indptr, w) + 1.0
    # weighted neighbourhood mean including the point itself
    mean = (_segment_sum(indptr, w[:, None] * points[indices]) + centres) / total[:, None]
    d = points[indices] - mean[rows]
    d0 = centres - mean
    cov = np.empty((n, 3, 3))
    for a, b in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)):
        entry = (_segment_sum(indptr, w * d[:, a] * d[:, b]) + d0[:, a] * d0[:, b]) / total
        cov[:, a, b] = cov[:, b, a] = entry
    return cov


def smallest_eigenvectors(cov):
    """Unit eigenvector of the smallest eigenvalue and the ascending eigenvalues (LAPACK)."""
    values, vectors = np.linalg.eigh(cov)
    return np.ascontiguousarray(vectors[:, :, 0]), values


def kappa_normal_sums(points, indptr, indices, distances, inv_4t, weights, areas, has_weights):
    """``sum_j W_ij A_j (x_i - x_j)`` per point, ``W`` given or the heat kernel."""
    rows = _rows(indptr)
    w = weights if has_weights else np.exp(-(distances**2) * inv_4t[rows])
    coupling = w * areas[indices]
    return _segment_sum(indptr, coupling[:, None] * (points[rows] - points[indices]))


def centroid_offsets(points, centres, indptr, indices, distances, radius, normals, start, use_taper):
    """``|P_t (mean_j x_j - x_i)| / R_i`` per point."""
    w = _taper(indptr, distances, radius, start) if use_taper else np.ones(indices.shape[0])
    total = np.maximum(_segment_sum(indptr, w), np.finfo(float).tiny)
    centroid = _segment_sum(indptr, w[:, None] * points[indices]) / total[:, None] - centres
    centroid -= np.einsum("ij,ij->i", centroid, normals)[:, None] * normals
    return np.linalg.norm(centroid, axis=1) / radius


def neighbour_medians(values, indptr, indices):
    """Median of ``values[j]`` over each row's neighbours; NaN for an empty row."""
    return np.array([
        np.median(values[indices[indptr[i]:indptr[i + 1]]]) if indptr[i + 1] > indptr[i] else np.nan
        for i in range(len(indptr) - 1)
    ])


def counts_below(values, factor, limits, indptr, indices):
    """Neighbours with ``factor * values[j] < limits[i]`` per row."""
    return _segment_sum(indptr, (factor * values[indices] < limits[_rows(indptr)]).astype(float)).astype(np.int64)


def same_label_counts(labels, indptr, indices):
    """Neighbours with ``labels[j] == labels[i]`` per row."""
    return _segment_sum(indptr, (labels[indices] == labels[_rows(indptr)]).astype(float)).astype(np.int64)


def orientation_conflicts(points, normals, indptr, indices, distances, in_plane, aligned):
    """Compared and opposed neighbours per row, shape (n, 2)."""
    rows = _rows(indptr)
    dot = np.einsum("ij,ij->i", normals[rows], normals[indices])
    height = np.abs(np.einsum("ij,ij->i", normals[rows], points[indices] - points[rows]))
    compared = (np.abs(dot) >= aligned) & (height <= in_plane * distances)
    return np.column_stack([
        _segment_sum(indptr, compared.astype(float)), _segment_sum(indptr, (compared & (dot < 0)).astype(float))
    ])


def opposite_sheet_counts(points, normals, indptr, indices, distances, reach, min_height, opposite):
    """Neighbours within reach, over or under the row's point, facing the other way, per row."""
    rows = _rows(indptr)
    dot = np.einsum("ij,ij->i", normals[rows], normals[indices])
    height = np.einsum("ij,ij->i", normals[rows], points[indices] - points[rows])
    counted = ((distances <= reach[rows]) & (dot < -opposite) & (np.abs(height) > min_height[rows])
               & (2.0 * height**2 > distances**2))
    return _segment_sum(indptr, counted.astype(float)).astype(np.int64)


def over_under_pairs(points, normals, indptr, indices, distances, reach, min_height, aligned):
    """Neighbours within reach, over or under the row's point, facing either way within ``aligned``, as pairs."""
    rows = _rows(indptr)
    dot = np.einsum("ij,ij->i", normals[rows], normals[indices])
    height = np.einsum("ij,ij->i", normals[rows], points[indices] - points[rows])
    kept = ((distances <= reach[rows]) & (np.abs(dot) > aligned) & (np.abs(height) > min_height[rows])
            & (2.0 * height**2 > distances**2))
    return rows[kept], np.asarray(indices)[kept], dot[kept]


def flagged_within(flags, indptr, indices, distances, reach):
    """Neighbours within reach, and how many of them are flagged, per row."""
    rows = _rows(indptr)
    within = distances <= reach[rows]
    return np.column_stack([_segment_sum(indptr, within.astype(float)),
                            _segment_sum(indptr, (within & flags[indices]).astype(float))]).astype(np.int64)


def quadric_residual_moments(points, normals, indptr, indices, scale):
    """Root mean square and kurtosis of the residuals of a least-squares quadric over each row and its point."""
    out = np.full((indptr.shape[0] - 1, 2), np.nan)
    for i in range(indptr.shape[0] - 1):
        n = normals[i]
        ball = np.vstack([points[i], points[indices[indptr[i]:indptr[i + 1]]]]) - points[i]
        if not np.all(np.isfinite(n)) or ball.shape[0] < 7 or not scale[i] > 0:
            continue
        # any orthonormal tangent frame: the residuals do not depend on it
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        x, y, z = ball @ u / scale[i], ball @ np.cross(n, u) / scale[i], ball @ n
        design = np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])
        coef = np.linalg.lstsq(design, z, rcond=None)[0]
        r = z - design @ coef
        out[i, 0] = np.sqrt(np.mean(r**2))
        if out[i, 0] > 0:
            out[i, 1] = np.mean(r**4) / np.mean(r**2) ** 2
    return out
