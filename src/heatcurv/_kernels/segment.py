"""Compiled kernels for the per-pair sums over CSR neighbourhoods.

Each kernel is a row core, ``_name(row0, row1, ..., out)``, that loops over the
points ``row0 <= i < row1`` and over each point's neighbours
``indices[indptr[i]:indptr[i+1]]``, so no per-pair temporary is ever
allocated; the public function of the same name without the underscore
allocates the output and runs the core on threads
(:func:`heatcurv._kernels.parallel_rows`). These are the only implementations the
stages run (:mod:`heatcurv.orient.normals`, :mod:`heatcurv.operators.kernel`,
:mod:`heatcurv.operators.areas`, :mod:`heatcurv.operators.mean_curvature`, :mod:`heatcurv.flags.border`
call them directly); ``tests/reference/segment.py`` holds their numpy
references, which the tests compare them with (to 1e-10 on sums).

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, as_indices, as_pointers, parallel_rows
from .chordfit import _cholesky, _cholesky_solve

__all__ = [
    "orientation_costs",
    "tapered_heat_weights",
    "taper_sums",
    "weighted_covariances",
    "smallest_eigenvectors",
    "kappa_normal_sums",
    "centroid_offsets",
    "neighbour_medians",
    "counts_below",
    "same_label_counts",
    "orientation_conflicts",
    "opposite_sheet_counts", "over_under_pairs",
    "quadric_residual_moments",
    "flagged_within",
]


@njit(inline="always", cache=True)
def _flat_top(u, start):
    # 1 up to `start`, raised cosine to 0 at u = 1 (heatcurv.operators.kernel.flat_top)
    if u >= 1.0:
        return 0.0
    if u <= start:
        return 1.0
    return 0.5 * (1.0 + math.cos(math.pi * (u - start) / (1.0 - start)))


def orientation_costs(points, normals, indptr, indices, distances, radius):
    """Spanning-tree edge costs of the orientation (heatcurv.orient.orientation.orient), shape (nnz,).

    ``1 - |s_ij| + max(|n_i . e|, |n_j . e|) + 1e-3 |xi - xj| / R_i + 1e-12`` with
    ``e = (xj - xi) / |xj - xi|`` and ``s_ij = n_i . n_j - (n_i . e)(n_j . e)``, the
    normals' agreement once their components along the edge are removed (which
    stays clear across a sharp edge, where ``n_i . n_j`` is near 0); the tilt term
    makes an edge that leaves the tangent planes (across a thin part) costly.
    """
    points, normals = as_floats(points), as_floats(normals)
    indptr, distances = as_pointers(indptr), as_floats(distances)
    out = np.empty(distances.shape[0])
    args = points, normals, indptr, as_indices(indices, normals.shape[0]), distances, as_floats(radius), out
    parallel_rows(_orientation_costs, indptr.shape[0] - 1, *args)
    return out


@njit(**ROW_CORE)
def _orientation_costs(row0, row1, points, normals, indptr, indices, distances, radius, out):
    for i in range(row0, row1):
        inv = 1e-3 / radius[i]
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            dot = normals[i, 0] * normals[j, 0] + normals[i, 1] * normals[j, 1] + normals[i, 2] * normals[j, 2]
            ti = 0.0
            tj = 0.0
            if distances[p] > 0.0:
                for a in range(3):
                    e = (points[j, a] - points[i, a]) / distances[p]
                    ti += normals[i, a] * e
                    tj += normals[j, a] * e
            out[p] = (1.0 - abs(dot - ti * tj)) + max(abs(ti), abs(tj)) + distances[p] * inv + 1e-12


def tapered_heat_weights(indptr, indices, distances, radius, inv_h2, areas, start):
    """``exp(-|xi - xj|^2 inv_h2[i]) flat_top(|xi - xj| / R_i) A_j`` per pair, shape (nnz,)."""
    indptr, distances, areas = as_pointers(indptr), as_floats(distances), as_floats(areas)
    out = np.empty(distances.shape[0])
    args = indptr, as_indices(indices, areas.shape[0]), distances, as_floats(radius), as_floats(inv_h2), areas
    parallel_rows(_tapered_heat_weights, indptr.shape[0] - 1, *args, float(start), out)
    return out


@njit(**ROW_CORE)
def _tapered_heat_weights(row0, row1, indptr, indices, distances, radius, inv_h2, areas, start, out):
    for i in range(row0, row1):
        inv = 1.0 / radius[i]
        for p in range(indptr[i], indptr[i + 1]):
            d = distances[p]
            out[p] = math.exp(-d * d * inv_h2[i]) * _flat_top(d * inv, start) * areas[indices[p]]


def taper_sums(indptr, distances, radius, start):
    """``sum_j flat_top(|xi - xj| / R_i)`` per point, shape (n,)."""
    indptr = as_pointers(indptr)
    n = indptr.shape[0] - 1
    out = np.zeros(n)
    parallel_rows(_taper_sums, n, indptr, as_floats(distances), as_floats(radius), float(start), out)
    return out


@njit(**ROW_CORE)
def _taper_sums(row0, row1, indptr, distances, radius, start, out):
    for i in range(row0, row1):
        s = 0.0
        inv = 1.0 / radius[i]
        for p in range(indptr[i], indptr[i + 1]):
            s += _flat_top(distances[p] * inv, start)
        out[i] = s


def weighted_covariances(points, indptr, indices, distances, radius, start, use_taper):
    """Covariance of each neighbourhood and its centre (weight 1), shape (n, 3, 3).

    Neighbour ``j`` has weight ``flat_top(|xi - xj| / R_i)`` (or 1), the centre
    weight 1; the mean is the weighted mean of the same points.
    """
    points, indptr = as_floats(points), as_pointers(indptr)
    n = indptr.shape[0] - 1
    cov = np.zeros((n, 3, 3))
    args = points, indptr, as_indices(indices, points.shape[0]), as_floats(distances), as_floats(radius)
    parallel_rows(_weighted_covariances, n, *args, float(start), bool(use_taper), cov)
    return cov


@njit(**ROW_CORE)
def _weighted_covariances(row0, row1, points, indptr, indices, distances, radius, start, use_taper, cov):
    longest = 0
    for i in range(row0, row1):
        longest = max(longest, indptr[i + 1] - indptr[i])
    weight = np.empty(longest)  # a row's weights, for its second pass (one cosine per pair, not two)
    for i in range(row0, row1):
        lo, hi = indptr[i], indptr[i + 1]
        inv = 1.0 / radius[i]
        total = 1.0
        m0, m1, m2 = points[i, 0], points[i, 1], points[i, 2]
        for p in range(lo, hi):
            w = _flat_top(distances[p] * inv, start) if use_taper else 1.0
            weight[p - lo] = w
            j = indices[p]
            total += w
            m0 += w * points[j, 0]
            m1 += w * points[j, 1]
            m2 += w * points[j, 2]
        m0 /= total
        m1 /= total
        m2 /= total
        d0, d1, d2 = points[i, 0] - m0, points[i, 1] - m1, points[i, 2] - m2
        c00, c01, c02, c11, c12, c22 = d0 * d0, d0 * d1, d0 * d2, d1 * d1, d1 * d2, d2 * d2
        for p in range(lo, hi):
            w = weight[p - lo]
            j = indices[p]
            d0, d1, d2 = points[j, 0] - m0, points[j, 1] - m1, points[j, 2] - m2
            c00 += w * d0 * d0
            c01 += w * d0 * d1
            c02 += w * d0 * d2
            c11 += w * d1 * d1
            c12 += w * d1 * d2
            c22 += w * d2 * d2
        cov[i, 0, 0] = c00 / total
        cov[i, 0, 1] = cov[i, 1, 0] = c01 / total
        cov[i, 0, 2] = cov[i, 2, 0] = c02 / total
        cov[i, 1, 1] = c11 / total
        cov[i, 1, 2] = cov[i, 2, 1] = c12 / total
        cov[i, 2, 2] = c22 / total


def kappa_normal_sums(points, indptr, indices, distances, inv_4t, weights, areas, has_weights):
    """``sum_j W_ij A_j (x_i - x_j)`` per point, shape (n, 3) (eq 2.10 without its constant).

    ``W_ij`` is ``weights[p]`` when ``has_weights``, else the heat kernel
    ``exp(-|xi - xj|^2 inv_4t[i])`` computed on the fly.
    """
    points, indptr = as_floats(points), as_pointers(indptr)
    n = indptr.shape[0] - 1
    out = np.zeros((n, 3))
    args = points, indptr, as_indices(indices, points.shape[0]), as_floats(distances), as_floats(inv_4t)
    parallel_rows(_kappa_normal_sums, n, *args, as_floats(weights), as_floats(areas), bool(has_weights), out)
    return out


@njit(**ROW_CORE)
def _kappa_normal_sums(row0, row1, points, indptr, indices, distances, inv_4t, weights, areas, has_weights, out):
    for i in range(row0, row1):
        s0 = s1 = s2 = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            w = weights[p] if has_weights else math.exp(-distances[p] * distances[p] * inv_4t[i])
            c = w * areas[j]
            s0 += c * (points[i, 0] - points[j, 0])
            s1 += c * (points[i, 1] - points[j, 1])
            s2 += c * (points[i, 2] - points[j, 2])
        out[i, 0], out[i, 1], out[i, 2] = s0, s1, s2


def centroid_offsets(points, centres, indptr, indices, distances, radius, normals, start, use_taper):
    """``|P_t (mean_j x_j - x_i)| / R_i`` per point (heatcurv.flags.border.centroid_offset)."""
    points, indptr = as_floats(points), as_pointers(indptr)
    n = indptr.shape[0] - 1
    out = np.zeros(n)
    args = points, as_floats(centres), indptr, as_indices(indices, points.shape[0]), as_floats(distances)
    args += as_floats(radius), as_floats(normals), float(start), bool(use_taper), out
    parallel_rows(_centroid_offsets, n, *args)
    return out


@njit(**ROW_CORE)
def _centroid_offsets(row0, row1, points, centres, indptr, indices, distances, radius, normals, start, use_taper, out):
    tiny = np.finfo(np.float64).tiny
    for i in range(row0, row1):
        inv = 1.0 / radius[i]
        total = 0.0
        c0 = c1 = c2 = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            w = _flat_top(distances[p] * inv, start) if use_taper else 1.0
            j = indices[p]
            total += w
            c0 += w * points[j, 0]
            c1 += w * points[j, 1]
            c2 += w * points[j, 2]
        total = max(total, tiny)
        c0 = c0 / total - centres[i, 0]
        c1 = c1 / total - centres[i, 1]
        c2 = c2 / total - centres[i, 2]
        dn = c0 * normals[i, 0] + c1 * normals[i, 1] + c2 * normals[i, 2]
        c0 -= dn * normals[i, 0]
        c1 -= dn * normals[i, 1]
        c2 -= dn * normals[i, 2]
        out[i] = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) * inv


@njit(cache=True)
def _jacobi_eigen3(a, v):
    """Eigen-decompose the symmetric 3 x 3 ``a`` in place by cyclic Jacobi rotations.

    On return the diagonal of ``a`` holds the eigenvalues and the columns of
    ``v`` the unit eigenvectors (Numerical Recipes' rotation formulas; each
    sweep squares the off-diagonal size, 3-5 sweeps reach rounding level).
    """
    for r in range(3):
        for c in range(3):
            v[r, c] = 1.0 if r == c else 0.0
    for _ in range(50):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        diag = a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2]
        if off <= 1e-36 * diag or off == 0.0:
            return
        for p, q in ((0, 1), (0, 2), (1, 2)):
            apq = a[p, q]
            if apq == 0.0:
                continue
            theta = (a[q, q] - a[p, p]) / (2.0 * apq)
            if abs(theta) > 1e150:
                t = 0.5 / theta
            else:
                t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
            c = 1.0 / math.sqrt(t * t + 1.0)
            s = t * c
            tau = s / (1.0 + c)
            a[p, p] -= t * apq
            a[q, q] += t * apq
            a[p, q] = a[q, p] = 0.0
            r = 3 - p - q  # the third index
            arp, arq = a[r, p], a[r, q]
            a[r, p] = a[p, r] = arp - s * (arq + tau * arp)
            a[r, q] = a[q, r] = arq + s * (arp - tau * arq)
            for k in range(3):
                vkp, vkq = v[k, p], v[k, q]
                v[k, p] = vkp - s * (vkq + tau * vkp)
                v[k, q] = vkq + s * (vkp - tau * vkq)


def smallest_eigenvectors(cov):
    """Unit eigenvector of the smallest eigenvalue and the sorted eigenvalues of each 3 x 3 matrix.

    Returns ``(vectors (n, 3), values (n, 3))``, values ascending; replaces a
    batched ``np.linalg.eigh`` (1.1 s for a million matrices, LAPACK's
    per-call overhead) by an inlined Jacobi iteration.
    """
    cov = as_floats(cov)
    n = cov.shape[0]
    vectors = np.empty((n, 3))
    values = np.empty((n, 3))
    parallel_rows(_smallest_eigenvectors, n, cov, vectors, values)
    return vectors, values


@njit(**ROW_CORE)
def _smallest_eigenvectors(row0, row1, cov, vectors, values):
    a = np.empty((3, 3))  # (allocated once per range of rows, not per matrix)
    v = np.empty((3, 3))
    for i in range(row0, row1):
        for r in range(3):
            for c in range(3):
                a[r, c] = cov[i, r, c]
        _jacobi_eigen3(a, v)
        l0, l1, l2 = a[0, 0], a[1, 1], a[2, 2]
        k = 0
        if l1 < l0 and l1 <= l2:
            k = 1
        elif l2 < l0 and l2 < l1:
            k = 2
        lo, mid, hi = l0, l1, l2
        # sort the three values
        if lo > mid:
            lo, mid = mid, lo
        if mid > hi:
            mid, hi = hi, mid
        if lo > mid:
            lo, mid = mid, lo
        values[i, 0], values[i, 1], values[i, 2] = lo, mid, hi
        vectors[i, 0], vectors[i, 1], vectors[i, 2] = v[0, k], v[1, k], v[2, k]


def neighbour_medians(values, indptr, indices):
    """Median of ``values[j]`` over each row's neighbours ``j``, shape (n,); NaN for an empty row.

    The mean of the two middle values of an even row, as :func:`numpy.median`.
    Each row is gathered into a buffer and its middle found by quickselect
    (linear in the row's length; no sort, no allocation per row).
    """
    values, indptr = as_floats(values), as_pointers(indptr)
    out = np.empty(indptr.shape[0] - 1)
    parallel_rows(_neighbour_medians, out.shape[0], values, indptr, as_indices(indices, values.shape[0]), out)
    return out


@njit(cache=True)
def _select(buffer, count, k):
    # quickselect (Hoare partition, middle pivot): buffer[k] becomes the k-th smallest of buffer[:count],
    # with nothing larger before it and nothing smaller after it
    lo = 0
    hi = count - 1
    while lo < hi:
        pivot = buffer[(lo + hi) // 2]
        i = lo
        j = hi
        while i <= j:
            while buffer[i] < pivot:
                i += 1
            while buffer[j] > pivot:
                j -= 1
            if i <= j:
                tmp = buffer[i]
                buffer[i] = buffer[j]
                buffer[j] = tmp
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return buffer[k]


@njit(**ROW_CORE)
def _neighbour_medians(row0, row1, values, indptr, indices, out):
    longest = 0
    for i in range(row0, row1):
        longest = max(longest, indptr[i + 1] - indptr[i])
    buffer = np.empty(longest)
    for i in range(row0, row1):
        start = indptr[i]
        count = indptr[i + 1] - start
        if count == 0:
            out[i] = np.nan
            continue
        for p in range(count):
            buffer[p] = values[indices[start + p]]
        upper = _select(buffer, count, count // 2)
        if count % 2 == 1:
            out[i] = upper
        else:
            # the lower middle is the largest of the part before the upper middle
            lower = buffer[0]
            for p in range(1, count // 2):
                lower = max(lower, buffer[p])
            out[i] = 0.5 * (lower + upper)


def counts_below(values, factor, limits, indptr, indices):
    """Per row ``i``, how many of its neighbours ``j`` have ``factor * values[j] < limits[i]``, shape (n,), int64.

    With ``limits = values`` this decides ``values[i] > factor * median`` for
    most rows without a median (:func:`heatcurv.flags.outliers.exceeds_neighbour_median`):
    a branch-free count instead of a selection.
    """
    values, indptr = as_floats(values), as_pointers(indptr)
    out = np.empty(indptr.shape[0] - 1, dtype=np.int64)
    args = values, float(factor), as_floats(limits), indptr, as_indices(indices, values.shape[0]), out
    parallel_rows(_counts_below, out.shape[0], *args)
    return out


@njit(**ROW_CORE)
def _counts_below(row0, row1, values, factor, limits, indptr, indices, out):
    for i in range(row0, row1):
        count = 0
        for p in range(indptr[i], indptr[i + 1]):
            count += factor * values[indices[p]] < limits[i]
        out[i] = count


def same_label_counts(labels, indptr, indices):
    """Per row ``i``, how many of its neighbours ``j`` have ``labels[j] == labels[i]``, shape (n,), int64."""
    labels, indptr = np.ascontiguousarray(labels, dtype=np.int64), as_pointers(indptr)
    out = np.empty(indptr.shape[0] - 1, dtype=np.int64)
    parallel_rows(_same_label_counts, out.shape[0], labels, indptr, as_indices(indices, labels.shape[0]), out)
    return out


@njit(**ROW_CORE)
def _same_label_counts(row0, row1, labels, indptr, indices, out):
    for i in range(row0, row1):
        count = 0
        for p in range(indptr[i], indptr[i + 1]):
            count += labels[indices[p]] == labels[i]
        out[i] = count


def orientation_conflicts(points, normals, indptr, indices, distances, in_plane, aligned):
    """Per row, the compared neighbours and those pointing the other way (heatcurv.orient.orientation), shape (n, 2).

    Neighbour ``j`` of ``i`` is compared when ``|n_i . (xj - xi)| <= in_plane |xj - xi|``
    and ``|n_i . n_j| >= aligned``; it points the other way when also ``n_i . n_j < 0``.
    Column 0 counts the compared, column 1 the opposed.
    """
    points, normals = as_floats(points), as_floats(normals)
    indptr, distances = as_pointers(indptr), as_floats(distances)
    out = np.zeros((indptr.shape[0] - 1, 2))
    args = points, normals, indptr, as_indices(indices, normals.shape[0]), distances, float(in_plane), float(aligned)
    parallel_rows(_orientation_conflicts, out.shape[0], *args, out)
    return out


@njit(**ROW_CORE)
def _orientation_conflicts(row0, row1, points, normals, indptr, indices, distances, in_plane, aligned, out):
    for i in range(row0, row1):
        compared = 0.0
        against = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            dot = normals[i, 0] * normals[j, 0] + normals[i, 1] * normals[j, 1] + normals[i, 2] * normals[j, 2]
            height = 0.0
            for a in range(3):
                height += normals[i, a] * (points[j, a] - points[i, a])
            if abs(dot) >= aligned and abs(height) <= in_plane * distances[p]:
                compared += 1.0
                if dot < 0.0:
                    against += 1.0
        out[i, 0] = compared
        out[i, 1] = against


def opposite_sheet_counts(points, normals, indptr, indices, distances, reach, min_height, opposite):
    """Per row ``i``, its neighbours on the other side of a thin part (heatcurv.flags.sheets), shape (n,), int64.

    Neighbour ``j`` within ``reach[i]`` of ``i`` counts when its height
    ``h = n_i . (xj - xi)`` exceeds both its distance from ``i``'s normal line
    and ``min_height[i]`` (:func:`_over_or_under`), and ``n_i . n_j < -opposite``.
    """
    points, normals = as_floats(points), as_floats(normals)
    indptr, distances = as_pointers(indptr), as_floats(distances)
    out = np.empty(indptr.shape[0] - 1, dtype=np.int64)
    args = (points, normals, indptr, as_indices(indices, normals.shape[0]), distances, as_floats(reach),
            as_floats(min_height), float(opposite))
    parallel_rows(_opposite_sheet_counts, out.shape[0], *args, out)
    return out


def over_under_pairs(points, normals, indptr, indices, distances, reach, min_height, aligned):
    """Each row's neighbours over or under it whose normals are near parallel either way, as pairs.

    As :func:`opposite_sheet_counts`, with ``|n_i . n_j| > aligned`` instead of
    ``n_i . n_j < -aligned``: the pairs whose facing decides whether they are
    two sides of a thin part once their normals' signs are known.

    Returns
    -------
    rows, columns : ndarray, shape (k,), int64
        The pairs ``(i, j)``, by row.
    dots : ndarray, shape (k,)
        ``n_i . n_j``.
    """
    points, normals = as_floats(points), as_floats(normals)
    indptr, distances = as_pointers(indptr), as_floats(distances)
    indices = as_indices(indices, normals.shape[0])
    args = (points, normals, indptr, indices, distances, as_floats(reach), as_floats(min_height), float(aligned))
    n = indptr.shape[0] - 1
    counts = np.zeros(n, dtype=np.int64)
    parallel_rows(_over_under_counts, n, *args, counts)
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=start[1:])
    columns, dots = np.empty(start[-1], dtype=np.int64), np.empty(start[-1])
    parallel_rows(_over_under_fill, n, *args, start, columns, dots)
    return np.repeat(np.arange(n, dtype=np.int64), counts), columns, dots


@njit(inline="always", cache=True)
def _over_or_under(points, normals, i, j, distance, min_height):
    """Whether ``j`` lies over or under ``i``: more than 45 degrees out of its tangent plane, above ``min_height``."""
    height = 0.0
    for a in range(3):
        height += normals[i, a] * (points[j, a] - points[i, a])
    # h^2 > |d|^2 - h^2
    return abs(height) > min_height and 2.0 * height * height > distance * distance


@njit(inline="always", cache=True)
def _normal_dot(normals, i, j):
    return normals[i, 0] * normals[j, 0] + normals[i, 1] * normals[j, 1] + normals[i, 2] * normals[j, 2]


@njit(**ROW_CORE)
def _opposite_sheet_counts(row0, row1, points, normals, indptr, indices, distances, reach, min_height, opposite,
                           out):
    for i in range(row0, row1):
        count = 0
        for p in range(indptr[i], indptr[i + 1]):
            # most neighbours fail the facing: their position is not read
            if distances[p] <= reach[i] and _normal_dot(normals, i, indices[p]) < -opposite and \
                    _over_or_under(points, normals, i, indices[p], distances[p], min_height[i]):
                count += 1
        out[i] = count


@njit(**ROW_CORE)
def _over_under_counts(row0, row1, points, normals, indptr, indices, distances, reach, min_height, aligned, out):
    for i in range(row0, row1):
        count = 0
        for p in range(indptr[i], indptr[i + 1]):
            if distances[p] <= reach[i] and abs(_normal_dot(normals, i, indices[p])) > aligned and \
                    _over_or_under(points, normals, i, indices[p], distances[p], min_height[i]):
                count += 1
        out[i] = count


@njit(**ROW_CORE)
def _over_under_fill(row0, row1, points, normals, indptr, indices, distances, reach, min_height, aligned, start,
                     columns, dots):
    for i in range(row0, row1):
        k = start[i]
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            dot = _normal_dot(normals, i, j)
            if distances[p] <= reach[i] and abs(dot) > aligned and \
                    _over_or_under(points, normals, i, j, distances[p], min_height[i]):
                columns[k] = j
                dots[k] = dot
                k += 1


def flagged_within(flags, indptr, indices, distances, reach):
    """Per row ``i``, its neighbours within ``reach[i]`` and how many of them are ``flags``, shape (n, 2), int64."""
    flags, indptr = np.ascontiguousarray(flags, dtype=np.bool_), as_pointers(indptr)
    out = np.empty((indptr.shape[0] - 1, 2), dtype=np.int64)
    parallel_rows(_flagged_within, out.shape[0], flags, indptr, as_indices(indices, flags.shape[0]),
                  as_floats(distances), as_floats(reach), out)
    return out


@njit(**ROW_CORE)
def _flagged_within(row0, row1, flags, indptr, indices, distances, reach, out):
    for i in range(row0, row1):
        within = flagged = 0
        for p in range(indptr[i], indptr[i + 1]):
            if distances[p] <= reach[i]:
                within += 1
                flagged += flags[indices[p]]
        out[i, 0], out[i, 1] = within, flagged


def quadric_residual_moments(points, normals, indptr, indices, scale):
    """Per row, the residual of a least-squares quadric over the point and its neighbours, shape (n, 2).

    In the frame of ``n_i`` (heights ``z = n_i . (xj - xi)``, tangent coordinates
    over ``scale[i]``), ``z = c0 + c1 x + c2 y + c3 x^2 + c4 x y + c5 y^2`` fitted
    with equal weights over the row's neighbours and the point itself. Column 0
    is the residuals' root mean square, column 1 their kurtosis
    ``mean(r^4) / mean(r^2)^2`` (NaN for a NaN normal, fewer than 7 points, a
    system that is not positive definite or residuals that are all 0).
    """
    points, normals = as_floats(points), as_floats(normals)
    indptr = as_pointers(indptr)
    out = np.empty((indptr.shape[0] - 1, 2))
    args = points, normals, indptr, as_indices(indices, normals.shape[0]), as_floats(scale), out
    parallel_rows(_quadric_residual_moments, out.shape[0], *args)
    return out


@njit(**ROW_CORE)
def _quadric_residual_moments(row0, row1, points, normals, indptr, indices, scale, out):
    width = 1
    for i in range(row0, row1):
        width = max(width, indptr[i + 1] - indptr[i] + 1)
    xs, ys, zs = np.empty(width), np.empty(width), np.empty(width)
    a, factor = np.empty((6, 6)), np.empty((6, 6))  # the normal equations and their Cholesky factor
    b, c = np.empty(6), np.empty(6)  # their right-hand side and the quadric's coefficients
    for i in range(row0, row1):
        out[i, 0] = out[i, 1] = np.nan
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        count = indptr[i + 1] - indptr[i] + 1  # the neighbours and the point itself (at the origin)
        if not (nx == nx and ny == ny and nz == nz) or count < 7 or not scale[i] > 0.0:
            continue
        # a tangent frame (u, v) of n_i, both of length 1 / scale[i]
        if abs(nx) < 0.9:
            ux, uy, uz = 0.0, nz, -ny
        else:
            ux, uy, uz = -nz, 0.0, nx
        norm = math.sqrt(ux * ux + uy * uy + uz * uz) * scale[i]
        ux, uy, uz = ux / norm, uy / norm, uz / norm
        vx, vy, vz = ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux
        # the power sums x^a y^b (a + b <= 4) and x^a y^b z (a + b <= 2) over the ball
        s10 = s01 = s20 = s11 = s02 = s30 = s21 = s12 = s03 = s40 = s31 = s22 = s13 = s04 = 0.0
        z0 = z10 = z01 = z20 = z11 = z02 = 0.0
        xs[0] = ys[0] = zs[0] = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            dx, dy, dz = points[j, 0] - points[i, 0], points[j, 1] - points[i, 1], points[j, 2] - points[i, 2]
            x, y, z = ux * dx + uy * dy + uz * dz, vx * dx + vy * dy + vz * dz, nx * dx + ny * dy + nz * dz
            k = p - indptr[i] + 1
            xs[k], ys[k], zs[k] = x, y, z
            xx, xy, yy = x * x, x * y, y * y
            s10 += x
            s01 += y
            s20 += xx
            s11 += xy
            s02 += yy
            s30 += xx * x
            s21 += xx * y
            s12 += x * yy
            s03 += yy * y
            s40 += xx * xx
            s31 += xx * xy
            s22 += xx * yy
            s13 += xy * yy
            s04 += yy * yy
            z0 += z
            z10 += x * z
            z01 += y * z
            z20 += xx * z
            z11 += xy * z
            z02 += yy * z
        # rows and columns in the order 1, x, y, x^2, x y, y^2
        a[0, 0], a[0, 1], a[0, 2], a[0, 3], a[0, 4], a[0, 5] = count, s10, s01, s20, s11, s02
        a[1, 1], a[1, 2], a[1, 3], a[1, 4], a[1, 5] = s20, s11, s30, s21, s12
        a[2, 2], a[2, 3], a[2, 4], a[2, 5] = s02, s21, s12, s03
        a[3, 3], a[3, 4], a[3, 5] = s40, s31, s22
        a[4, 4], a[4, 5] = s22, s13
        a[5, 5] = s04
        b[0], b[1], b[2], b[3], b[4], b[5] = z0, z10, z01, z20, z11, z02
        for r in range(6):
            for k in range(r):
                a[r, k] = a[k, r]
        if not _cholesky(a, factor):
            continue
        _cholesky_solve(factor, b, c)
        m2 = m4 = 0.0
        for k in range(count):
            x, y = xs[k], ys[k]
            r = zs[k] - (c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y)
            r *= r
            m2 += r
            m4 += r * r
        m2 /= count
        m4 /= count
        out[i, 0] = math.sqrt(m2)
        if m2 > 0.0:
            out[i, 1] = m4 / (m2 * m2)
