"""Compiled kernels of the default point-cloud Laplacian (:mod:`heatcurv.operators.point_laplacian`).

* :func:`knn_covariances`: the 3 x 3 covariance of each point's nearest
  neighbours (and itself), for the tangent plane of its Voronoi cell;
* :func:`voronoi_cells`: each point's Voronoi cell among its projected nearest
  neighbours, in its tangent plane (half-plane clipping of a square), its
  area, whether it is open (a vertex far out: a border of the cloud, or a
  cell the neighbours do not close) and, for the open cells, the clip at a
  given distance beyond the point, normal to the direction in which the cell
  opens (the mean of its far vertices);
* :func:`border_moments`: each row's weighted tangential first moment
  ``sum_j w_ij P_i (x_j - x_i)`` (the centroid offset of a cut ball) and
  weight sum;
* :func:`moment_weights`: the calibration weights of each pair, the
  isotropic ``|d|^2`` blended into the border-tangential ``2 (d . v_i)^2``;
* :func:`pair_second_moments`, :func:`tangent_gradient`, :func:`weak_divergence`,
  :func:`arc_over_chord`: the heat method's least-squares gradient, its
  adjoint divergence over the operator's pair weights and each pair's arc
  over the surface (:mod:`heatcurv.operators.geodesic`).

Arrays in, arrays out: this module imports nothing from heatcurv but the
kernel helpers of :mod:`heatcurv._kernels`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, as_indices, as_pointers, parallel_rows

__all__ = ["knn_covariances", "voronoi_cells", "border_moments", "moment_weights", "pair_second_moments",
           "tangent_gradient", "weak_divergence", "arc_over_chord"]


def knn_covariances(points, neighbours) -> np.ndarray:
    """Covariance of each point with its nearest neighbours.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    neighbours : ndarray, shape (n, k), int
        Indices of each point's ``k`` nearest neighbours (itself excluded).

    Returns
    -------
    ndarray, shape (n, 3, 3)
        Covariance of the ``k + 1`` points about their mean.
    """
    points = as_floats(points)
    neighbours = np.ascontiguousarray(neighbours, dtype=np.int64)
    cov = np.empty((points.shape[0], 3, 3))
    parallel_rows(_knn_covariances, points.shape[0], points, neighbours, cov)
    return cov


@njit(**ROW_CORE)
def _knn_covariances(row0, row1, points, neighbours, cov):
    k = neighbours.shape[1]
    for i in range(row0, row1):
        m0 = points[i, 0]
        m1 = points[i, 1]
        m2 = points[i, 2]
        for j in range(k):
            p = neighbours[i, j]
            m0 += points[p, 0]
            m1 += points[p, 1]
            m2 += points[p, 2]
        m0 /= k + 1
        m1 /= k + 1
        m2 /= k + 1
        c00 = c01 = c02 = c11 = c12 = c22 = 0.0
        for j in range(-1, k):
            p = i if j < 0 else neighbours[i, j]
            a = points[p, 0] - m0
            b = points[p, 1] - m1
            c = points[p, 2] - m2
            c00 += a * a
            c01 += a * b
            c02 += a * c
            c11 += b * b
            c12 += b * c
            c22 += c * c
        cov[i, 0, 0] = c00
        cov[i, 0, 1] = c01
        cov[i, 0, 2] = c02
        cov[i, 1, 0] = c01
        cov[i, 1, 1] = c11
        cov[i, 1, 2] = c12
        cov[i, 2, 0] = c02
        cov[i, 2, 1] = c12
        cov[i, 2, 2] = c22


def voronoi_cells(points, neighbours, normals, gap, reach=1.0) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-plane Voronoi cell areas of each point among its nearest neighbours.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    neighbours : ndarray, shape (n, k), int
        Each point's ``k`` nearest neighbours, itself excluded.
    normals : ndarray, shape (n, 3)
        Unit normals: the cell is computed in the plane through the point
        normal to it, each neighbour placed in the direction of its
        projection at its distance from the point (a first-order logarithmic
        map: orthogonal projection would shrink the cells by the curvature,
        -0.56 % on the area of a 5000 point torus, this -0.13 %).
    gap : ndarray, shape (n,)
        Where positive and the cell is open, the cell is also clipped by the
        line at this distance beyond the point, normal to the direction in
        which the cell opens (the mean of its vertices beyond ``reach * d_k``).
    reach : float, optional
        Open-cell threshold in units of ``d_k`` (see ``opened``).

    Returns
    -------
    area : ndarray, shape (n,)
        Cell areas. A cell starts as the square of half-side ``2 d_k`` (``d_k``
        the distance to the ``k``-th neighbour) about the point.
    opened : ndarray, shape (n,), bool
        Cells with a vertex farther than ``reach * d_k`` from the point
        (before the gap's clip): a border of the cloud (or, rarely, a cell
        that the ``k`` neighbours do not close).
    """
    points = as_floats(points)
    neighbours = np.ascontiguousarray(neighbours, dtype=np.int64)
    n = points.shape[0]
    area = np.empty(n)
    opened = np.zeros(n, dtype=np.bool_)
    parallel_rows(_voronoi_cells, n, points, neighbours, as_floats(normals), as_floats(gap), float(reach), area, opened)
    return area, opened


@njit(**ROW_CORE)
def _clip(px, py, nv, a, b, c, qx, qy):
    """Clip the convex polygon ``(px, py)[:nv]`` to ``a x + b y <= c`` into ``(qx, qy)``; the new vertex count."""
    m = 0
    for v in range(nv):
        w = v + 1 if v + 1 < nv else 0
        fv = a * px[v] + b * py[v] - c
        fw = a * px[w] + b * py[w] - c
        if fv <= 0.0:
            qx[m] = px[v]
            qy[m] = py[v]
            m += 1
        if (fv < 0.0 and fw > 0.0) or (fv > 0.0 and fw < 0.0):
            s = fv / (fv - fw)
            qx[m] = px[v] + s * (px[w] - px[v])
            qy[m] = py[v] + s * (py[w] - py[v])
            m += 1
    return m


@njit(**ROW_CORE)
def _voronoi_cells(row0, row1, points, neighbours, normals, gap, reach, area, opened):
    k = neighbours.shape[1]
    cap = 2 * k + 16
    px = np.empty(cap)
    py = np.empty(cap)
    qx = np.empty(cap)
    qy = np.empty(cap)
    ux = np.empty(k)
    uy = np.empty(k)
    for i in range(row0, row1):
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        if abs(nx) < 0.9:
            ax, ay, az = 1.0, 0.0, 0.0
        else:
            ax, ay, az = 0.0, 1.0, 0.0
        dot = ax * nx + ay * ny + az * nz
        e1x, e1y, e1z = ax - dot * nx, ay - dot * ny, az - dot * nz
        norm = np.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
        e1x /= norm
        e1y /= norm
        e1z /= norm
        e2x = ny * e1z - nz * e1y
        e2y = nz * e1x - nx * e1z
        e2z = nx * e1y - ny * e1x
        half = 0.0
        for j in range(k):
            p = neighbours[i, j]
            dx = points[p, 0] - points[i, 0]
            dy = points[p, 1] - points[i, 1]
            dz = points[p, 2] - points[i, 2]
            ux[j] = dx * e1x + dy * e1y + dz * e1z
            uy[j] = dx * e2x + dy * e2y + dz * e2z
            r = np.sqrt(dx * dx + dy * dy + dz * dz)
            # the projected direction at the chord's length (a first-order logarithmic map): an
            # orthogonal projection shortens the distances and the cells by the curvature
            plane = np.sqrt(ux[j] * ux[j] + uy[j] * uy[j])
            if plane > 0.0:
                ux[j] *= r / plane
                uy[j] *= r / plane
            if 2.0 * r > half:
                half = 2.0 * r
        px[0], py[0] = -half, -half
        px[1], py[1] = half, -half
        px[2], py[2] = half, half
        px[3], py[3] = -half, half
        nv = 4
        for j in range(k):
            nv = _clip(px, py, nv, ux[j], uy[j], 0.5 * (ux[j] * ux[j] + uy[j] * uy[j]), qx, qy)
            for v in range(nv):
                px[v] = qx[v]
                py[v] = qy[v]
        # open: a vertex beyond reach * d_k (d_k = half / 2)
        # the outward direction: the mean of the far vertices (where the cell opens)
        far = (0.5 * reach * half) ** 2
        is_open = False
        cx = 0.0
        cy = 0.0
        for v in range(nv):
            if px[v] * px[v] + py[v] * py[v] > far:
                is_open = True
                cx += px[v]
                cy += py[v]
        norm = np.sqrt(cx * cx + cy * cy)
        if is_open and gap[i] > 0.0 and norm > 0.0:
            nv = _clip(px, py, nv, cx / norm, cy / norm, gap[i], qx, qy)
            for v in range(nv):
                px[v] = qx[v]
                py[v] = qy[v]
        s = 0.0
        for v in range(nv):
            w = v + 1 if v + 1 < nv else 0
            s += px[v] * py[w] - px[w] * py[v]
        area[i] = 0.5 * abs(s)
        opened[i] = is_open


def _weighted_pairs(points, indptr, indices, weights) -> tuple:
    """``(points, indptr, indices, weights)`` in the one type each the pair kernels below take."""
    points = as_floats(points)
    return points, as_pointers(indptr), as_indices(indices, points.shape[0]), as_floats(weights)


def border_moments(points, indptr, indices, weights, normals) -> tuple[np.ndarray, np.ndarray]:
    """Weighted tangential first moment and weight sum of each CSR row.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    indptr, indices : ndarray
        CSR pairs, row ``i`` holding the neighbours of point ``i``.
    weights : ndarray, shape (nnz,)
        Pair weights ``w_ij``.
    normals : ndarray, shape (n, 3)
        Unit normals ``n_i``.

    Returns
    -------
    moment : ndarray, shape (n, 3)
        ``sum_j w_ij (I - n_i n_i^T)(x_j - x_i)``.
    total : ndarray, shape (n,)
        ``sum_j w_ij``.
    """
    pairs = _weighted_pairs(points, indptr, indices, weights)
    n = pairs[0].shape[0]
    moment = np.zeros((n, 3))
    total = np.zeros(n)
    parallel_rows(_border_moments, n, *pairs, as_floats(normals), moment, total)
    return moment, total


@njit(**ROW_CORE)
def _border_moments(row0, row1, points, indptr, indices, weights, normals, moment, total):
    for i in range(row0, row1):
        m0 = m1 = m2 = s = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            w = weights[p]
            m0 += w * (points[j, 0] - points[i, 0])
            m1 += w * (points[j, 1] - points[i, 1])
            m2 += w * (points[j, 2] - points[i, 2])
            s += w
        dot = m0 * normals[i, 0] + m1 * normals[i, 1] + m2 * normals[i, 2]
        moment[i, 0] = m0 - dot * normals[i, 0]
        moment[i, 1] = m1 - dot * normals[i, 1]
        moment[i, 2] = m2 - dot * normals[i, 2]
        total[i] = s


def moment_weights(points, indptr, indices, weights, beta, along) -> np.ndarray:
    """Second-moment weights ``w_ij ((1 - beta_i) |d|^2 + 2 beta_i (d . v_i)^2) / 4``, ``d = x_j - x_i``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    indptr, indices : ndarray
        CSR pairs.
    weights : ndarray, shape (nnz,)
        Pair weights ``w_ij``.
    beta : ndarray, shape (n,)
        Blend in [0, 1] of each row.
    along : ndarray, shape (n, 3)
        Unit vector ``v_i`` (along the border, in the tangent plane).

    Returns
    -------
    ndarray, shape (nnz,)
    """
    pairs = _weighted_pairs(points, indptr, indices, weights)
    n = pairs[0].shape[0]
    out = np.empty(len(indices))
    parallel_rows(_moment_weights, n, *pairs, as_floats(beta), as_floats(along), out)
    return out


@njit(**ROW_CORE)
def _moment_weights(row0, row1, points, indptr, indices, weights, beta, along, out):
    for i in range(row0, row1):
        b = beta[i]
        if b > 0.0:
            # a half disc has 2 sum (d . v)^2 = sum |d|^2; a row far from that (a corner, a strip one point
            # wide) keeps the isotropic calibration: its border direction is not defined
            iso = 0.0
            along_sum = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                d0 = points[j, 0] - points[i, 0]
                d1 = points[j, 1] - points[i, 1]
                d2 = points[j, 2] - points[i, 2]
                dv = d0 * along[i, 0] + d1 * along[i, 1] + d2 * along[i, 2]
                iso += weights[p] * (d0 * d0 + d1 * d1 + d2 * d2)
                along_sum += 2.0 * weights[p] * dv * dv
            if not along_sum > 0.5 * iso:
                b = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            d0 = points[j, 0] - points[i, 0]
            d1 = points[j, 1] - points[i, 1]
            d2 = points[j, 2] - points[i, 2]
            iso = d0 * d0 + d1 * d1 + d2 * d2
            dv = d0 * along[i, 0] + d1 * along[i, 1] + d2 * along[i, 2]
            out[p] = 0.25 * weights[p] * ((1.0 - b) * iso + 2.0 * b * dv * dv)


def pair_second_moments(points, indptr, indices, weights) -> np.ndarray:
    """Weighted second moment ``sum_j w_ij d_ij d_ij^T`` of each CSR row, ``d_ij = x_j - x_i``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    indptr, indices : ndarray
        CSR pairs, row ``i`` holding the neighbours of point ``i``.
    weights : ndarray, shape (nnz,)
        Pair weights ``w_ij``.

    Returns
    -------
    ndarray, shape (n, 3, 3)
    """
    pairs = _weighted_pairs(points, indptr, indices, weights)
    n = pairs[0].shape[0]
    second = np.zeros((n, 3, 3))
    parallel_rows(_pair_second_moments, n, *pairs, second)
    return second


@njit(**ROW_CORE)
def _pair_second_moments(row0, row1, points, indptr, indices, weights, second):
    d = np.empty(3)
    for i in range(row0, row1):
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            w = weights[p]
            for a in range(3):
                d[a] = points[j, a] - points[i, a]
            for a in range(3):
                for b in range(3):
                    second[i, a, b] += w * d[a] * d[b]


def tangent_gradient(points, indptr, indices, weights, inverse, values) -> np.ndarray:
    """Weighted least-squares slope of a field over each CSR row: ``P_i sum_j w_ij (u_j - u_i) d_ij``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    indptr, indices : ndarray
        CSR pairs.
    weights : ndarray, shape (nnz,)
        Pair weights ``w_ij``.
    inverse : ndarray, shape (n, 3, 3)
        ``P_i``: the (pseudo-)inverse of each row's second moment.
    values : ndarray, shape (n,)
        The field ``u``.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    pairs = _weighted_pairs(points, indptr, indices, weights)
    n = pairs[0].shape[0]
    out = np.empty((n, 3))
    parallel_rows(_tangent_gradient, n, *pairs, as_floats(inverse), as_floats(values), out)
    return out


@njit(**ROW_CORE)
def _tangent_gradient(row0, row1, points, indptr, indices, weights, inverse, values, out):
    for i in range(row0, row1):
        s0 = s1 = s2 = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            c = weights[p] * (values[j] - values[i])
            s0 += c * (points[j, 0] - points[i, 0])
            s1 += c * (points[j, 1] - points[i, 1])
            s2 += c * (points[j, 2] - points[i, 2])
        for a in range(3):
            out[i, a] = inverse[i, a, 0] * s0 + inverse[i, a, 1] * s1 + inverse[i, a, 2] * s2


def weak_divergence(points, indptr, indices, weights, field) -> np.ndarray:
    """The weak divergence of a vector field against the pair energy: ``-sum_j w_ij (X_i + X_j) / 2 . d_ij``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    indptr, indices : ndarray
        CSR pairs of a symmetric weight matrix.
    weights : ndarray, shape (nnz,)
        Pair weights ``w_ij``.
    field : ndarray, shape (n, 3)
        ``X_i`` at each point.

    Returns
    -------
    ndarray, shape (n,)
        ``b_i``, with ``d_ij = x_j - x_i``.
    """
    pairs = _weighted_pairs(points, indptr, indices, weights)
    n = pairs[0].shape[0]
    out = np.empty(n)
    parallel_rows(_weak_divergence, n, *pairs, as_floats(field), out)
    return out


@njit(**ROW_CORE)
def _weak_divergence(row0, row1, points, indptr, indices, weights, field, out):
    for i in range(row0, row1):
        s = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            s += weights[p] * ((field[i, 0] + field[j, 0]) * (points[j, 0] - points[i, 0])
                               + (field[i, 1] + field[j, 1]) * (points[j, 1] - points[i, 1])
                               + (field[i, 2] + field[j, 2]) * (points[j, 2] - points[i, 2]))
        out[i] = -0.5 * s


def arc_over_chord(points, indptr, indices, normals) -> np.ndarray:
    """Each pair's arc over the surface per unit of chord, ``1 + (h_i^2 + h_j^2) / (12 |d_ij|^2)``.

    ``h_i = n_i . d_ij`` and ``h_j = n_j . d_ij`` are the heights of each point
    over the other's tangent plane (``d_ij = x_j - x_i``); over a quadric the
    arc is ``c + h^2 / (6 c)`` to third order (``c`` the chord), and this
    averages the two ends. 1 on a plane.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    indptr, indices : ndarray
        CSR pairs.
    normals : ndarray, shape (n, 3)
        Unit normals (either sign).

    Returns
    -------
    ndarray, shape (nnz,)
    """
    points, indptr = as_floats(points), as_pointers(indptr)
    indices = as_indices(indices, points.shape[0])
    out = np.empty(indices.shape[0])
    parallel_rows(_arc_over_chord, indptr.shape[0] - 1, points, indptr, indices, as_floats(normals), out)
    return out


@njit(**ROW_CORE)
def _arc_over_chord(row0, row1, points, indptr, indices, normals, out):
    for i in range(row0, row1):
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            h_i = 0.0
            h_j = 0.0
            c2 = 0.0
            for a in range(3):
                d = points[j, a] - points[i, a]
                h_i += normals[i, a] * d
                h_j += normals[j, a] * d
                c2 += d * d
            out[p] = 1.0 + (h_i * h_i + h_j * h_j) / (12.0 * c2) if c2 > 0.0 else 1.0
