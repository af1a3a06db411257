"""Compiled carrying of anchor fits to the points around them (:mod:`heatcurv.anchors`).

Each anchor ``a`` has a chord fit in its frame ``(e1, e2, n)`` with ball radius
``R``: tensor ``(A, B, D)``, tilt ``(t1, t2)`` and cubic ``(g0, g1, g2, g3)``
coefficients in units of ``R`` (the columns of :mod:`heatcurv._kernels.chordfit`).
The fit says that a neighbour at tangential offset ``(x, y)`` (units of ``R``,
``r^2 = x^2 + y^2``) and height ``z`` has the chord curvature
``kN = -2 z / (r^2 + z^2) = P(x, y) / r^2`` with the polynomial

    P = A x^2 + 2 B x y + D y^2 + t1 x + t2 y + g0 x^3 + g1 x^2 y + g2 x y^2 + g3 y^3

(the columns ``c^2, 2 c s, s^2, c / r, s / r, r c^3 ...`` times ``r^2``). Without the
tilt this is the algebraic surface

    F(x, y, w) = P(x, y) (x^2 + y^2 + w^2) + 2 w (x^2 + y^2) = 0

(a sphere when ``P = A r^2``); the tilt, the small turn of the tangent plane the fit
found, shears it, ``w = z + (t1 x + t2 y) / 2`` (as the tilt term itself, a
chord model with tilt would be a cone at the anchor, of curvature ``~ t^2 / r``).
A point ``p`` near ``a`` gets from it that surface's normal ``grad F / |grad F|``
and curvature tensor ``P_t (Hess F) P_t / |grad F|`` (``P_t`` the projection onto
the tangent plane) at the model's point above ``p``'s offset, the root
``w = -P / (1 + sqrt(1 - P^2 / r^2))``: exact on the model surface, to every order
the model has. A noisy model (``exact`` 0, :data:`heatcurv.anchors.EXACT_CARRY_SIGMA`)
is carried to first order in the offset instead: the normal
``sqrt(1 - |s|^2) n + s_1 e1 + s_2 e2`` of the slope ``s = grad P / 2`` (exact on a
circle) and the tensor ``[[A + 3 g0 x + g1 y, B + g1 x + g2 y], [., D + g2 x + 3 g3 y]] / R``
carried into its tangent plane by the smallest rotation taking ``n`` to it (exact on a
sphere). The point's values are the weighted means over its nearest anchors, with weights
``(1 - (d / d_max)^2)^2 (1 - (d / R)^2)^2`` (``d_max`` just beyond the row's farthest
anchor): smooth as anchors enter or leave a point's list, zero outside an anchor's ball.

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, as_indices, as_pointers, parallel_rows

__all__ = ["carry_anchor_fits", "MAX_SLOPE", "MIN_AGREEMENT"]

#: An anchor whose model turns the normal by more than this sine at a point (about 64 degrees)
#: says nothing reliable there: it gets no weight.
MAX_SLOPE = 0.9
#: Least cosine between an anchor's normal and a point's own for the anchor to be carried to it.
MIN_AGREEMENT = 0.5
# the entries xx, xy, xz, yy, yz, zz of a symmetric 3 x 3 tensor
_ROW = (0, 0, 0, 1, 1, 2)
_COL = (0, 1, 2, 1, 2, 2)


def carry_anchor_fits(points, indptr, indices, distances, anchors, normals, e1, e2, coefficients, radius, usable,
                      scalars, reference=None, exact=None):
    """Every point's normal, curvature tensor and scalars from its nearest anchors' fits.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    indptr, indices, distances : ndarray
        CSR rows: each point's nearest anchors (indices into the anchor arrays)
        and their distances.
    anchors : ndarray, shape (m, 3)
        Anchor positions.
    normals, e1, e2 : ndarray, shape (m, 3)
        Each anchor fit's frame.
    coefficients : ndarray, shape (m, 9)
        Tensor, tilt and cubic coefficients, units of ``radius``.
    radius : ndarray, shape (m,)
        Each anchor's ball radius.
    usable : ndarray, shape (m,)
        1.0 for anchors whose fit may be used, 0.0 for the others (ill-posed).
    scalars : ndarray, shape (m, s)
        Per-anchor values averaged with the same weights, except the first
        (the fit's residual), which is the most-weighted anchor's: averaging
        would dilute a tree crown's large residuals with the ground's around it.
    reference : ndarray, shape (n, 3), optional
        Each point's own oriented normal: an anchor whose normal is more than
        60 degrees from it (:data:`MIN_AGREEMENT`; the other side of a part
        thinner than the ball) is not carried to the point.
    exact : ndarray, shape (m,), optional
        1.0 for anchors whose model is carried exactly, 0.0 for those carried to first
        order in the offset (noisy models); default all exactly.

    Returns
    -------
    normals : ndarray, shape (n, 3)
        Weighted sums of the carried unit normals (not normalised).
    tensor : ndarray, shape (n, 6)
        Weighted means of the carried tensors, ``xx, xy, xz, yy, yz, zz``.
    scalars : ndarray, shape (n, s)
        Weighted means (the first column: the most-weighted anchor's).
    support : ndarray, shape (n,)
        ``max (d + R)`` over the anchors with weight: how far the point's values reach.
    total : ndarray, shape (n,)
        Sum of the weights (0: no anchor applies; the nearest usable one was carried alone).
    """
    n = indptr.shape[0] - 1
    scalars = as_floats(scalars)
    check = reference is not None
    reference = as_floats(reference) if check else np.zeros((1, 3))
    out_n = np.empty((n, 3))
    out_t = np.empty((n, 6))
    out_s = np.empty((n, scalars.shape[1]))
    support = np.empty(n)
    total = np.empty(n)
    args = (
        as_floats(points), as_pointers(indptr), as_indices(indices, anchors.shape[0]), as_floats(distances),
        as_floats(anchors), as_floats(normals), as_floats(e1), as_floats(e2), as_floats(coefficients),
        as_floats(radius), as_floats(usable),
        np.ones(anchors.shape[0]) if exact is None else as_floats(exact), scalars, reference, check,
        out_n, out_t, out_s, support, total,
    )
    parallel_rows(_carry_anchor_fits, n, *args)
    return out_n, out_t, out_s, support, total


@njit(**ROW_CORE, inline="always")
def _tangent_offset(i, a, points, anchors, e1, e2, R):
    """Point ``i``'s offset from anchor ``a`` in the anchor's tangent frame, in ball radii ``R``: ``(x, y)``."""
    dx = points[i, 0] - anchors[a, 0]
    dy = points[i, 1] - anchors[a, 1]
    dz = points[i, 2] - anchors[a, 2]
    return (dx * e1[a, 0] + dy * e1[a, 1] + dz * e1[a, 2]) / R, (dx * e2[a, 0] + dy * e2[a, 1] + dz * e2[a, 2]) / R


@njit(**ROW_CORE, inline="always")
def _carry_one(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, grad, hess):
    """Anchor ``a``'s normal (into ``nrm``) and tensor (into ``tensor``) at point ``i``; False if too steep.

    The model surface ``F = P (x^2 + y^2 + z^2) + 2 z (x^2 + y^2) = 0`` (module docstring) at the
    point's tangential offset: its unit gradient is the normal and its Hessian, projected onto the
    tangent plane and divided by the gradient's length, the curvature tensor. ``grad`` (shape (3,))
    and ``hess`` (shape (6,)) are scratch space.
    """
    R = radius[a]
    x, y = _tangent_offset(i, a, points, anchors, e1, e2, R)
    q = x * x + y * y
    if not q > 1e-24:  # (at the anchor itself: its limit along e1)
        x, y, q = 1e-12, 0.0, 1e-24
    c = coefficients[a]
    xx, xy, yy = x * x, x * y, y * y
    # the shape without the tilt (a chord model with tilt is a cone at the anchor, of curvature ~ t^2 / r)
    P = c[0] * xx + 2 * c[1] * xy + c[2] * yy
    P += c[5] * xx * x + c[6] * xx * y + c[7] * x * yy + c[8] * yy * y
    Px = 2 * c[0] * x + 2 * c[1] * y + 3 * c[5] * xx + 2 * c[6] * xy + c[7] * yy
    Py = 2 * c[1] * x + 2 * c[2] * y + c[6] * xx + 2 * c[7] * xy + 3 * c[8] * yy
    Pxx = 2 * c[0] + 6 * c[5] * x + 2 * c[6] * y
    Pxy = 2 * c[1] + 2 * c[6] * x + 2 * c[7] * y
    Pyy = 2 * c[2] + 2 * c[7] * x + 6 * c[8] * y
    root = 1.0 - P * P / q
    if not root > 0.0:  # no point of the model above the offset (also false for nan)
        return False
    z = -P / (1.0 + math.sqrt(root))  # the model's height at the offset (the root through the anchor)
    rho = q + z * z
    grad[0] = Px * rho + 2 * x * P + 4 * x * z
    grad[1] = Py * rho + 2 * y * P + 4 * y * z
    grad[2] = 2 * z * P + 2 * q
    hess[0] = Pxx * rho + 4 * x * Px + 2 * P + 4 * z
    hess[1] = Pxy * rho + 2 * y * Px + 2 * x * Py
    hess[2] = 2 * z * Px + 4 * x
    hess[3] = Pyy * rho + 4 * y * Py + 2 * P + 4 * z
    hess[4] = 2 * z * Py + 4 * y
    hess[5] = 2 * P
    # the tilt shears the shape: w = z + (t1 x + t2 y) / 2, so grad F = J^T grad, Hess F = J^T Hess J with
    # J = I + e_z tau^T, tau = (t1, t2, 0) / 2
    tau0, tau1 = 0.5 * c[3], 0.5 * c[4]
    hz0, hz1, hz2 = hess[2], hess[4], hess[5]  # the Hessian's last column
    hess[0] += 2 * tau0 * hz0 + tau0 * tau0 * hz2
    hess[1] += tau0 * hz1 + tau1 * hz0 + tau0 * tau1 * hz2
    hess[2] += tau0 * hz2
    hess[3] += 2 * tau1 * hz1 + tau1 * tau1 * hz2
    hess[4] += tau1 * hz2
    grad[0] += tau0 * grad[2]
    grad[1] += tau1 * grad[2]
    length = math.sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2])
    if not length > 0.0:
        return False
    g0, g1, g2 = grad[0] / length, grad[1] / length, grad[2] / length
    # the normal's sine from the anchor's normal (its cosine is g2): too steep says nothing reliable
    if not g2 > 0.0 or not g0 * g0 + g1 * g1 < MAX_SLOPE * MAX_SLOPE:
        return False
    # T = P_t H P_t / |grad F| (P_t = I - g g^T), in the anchor's frame, then into the cloud's axes
    h00, h01, h02, h11, h12, h22 = hess[0], hess[1], hess[2], hess[3], hess[4], hess[5]
    hg0 = h00 * g0 + h01 * g1 + h02 * g2
    hg1 = h01 * g0 + h11 * g1 + h12 * g2
    hg2 = h02 * g0 + h12 * g1 + h22 * g2
    ghg = g0 * hg0 + g1 * hg1 + g2 * hg2
    scale = 1.0 / (length * R)
    t00 = (h00 - 2 * g0 * hg0 + g0 * g0 * ghg) * scale
    t01 = (h01 - g0 * hg1 - g1 * hg0 + g0 * g1 * ghg) * scale
    t02 = (h02 - g0 * hg2 - g2 * hg0 + g0 * g2 * ghg) * scale
    t11 = (h11 - 2 * g1 * hg1 + g1 * g1 * ghg) * scale
    t12 = (h12 - g1 * hg2 - g2 * hg1 + g1 * g2 * ghg) * scale
    t22 = (h22 - 2 * g2 * hg2 + g2 * g2 * ghg) * scale
    for k in range(3):
        nrm[k] = g0 * e1[a, k] + g1 * e2[a, k] + g2 * normals[a, k]
    for t in range(6):
        r, s = _ROW[t], _COL[t]
        u0, u1, u2 = e1[a, r], e2[a, r], normals[a, r]
        v0, v1, v2 = e1[a, s], e2[a, s], normals[a, s]
        tensor[t] = (u0 * (t00 * v0 + t01 * v1 + t02 * v2) + u1 * (t01 * v0 + t11 * v1 + t12 * v2)
                     + u2 * (t02 * v0 + t12 * v1 + t22 * v2))
    return True


@njit(**ROW_CORE, inline="always")
def _carry_first_order(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, frame_u, frame_v):
    """:func:`_carry_one` to first order in the offset, for noisy models (:data:`EXACT_CARRY_SIGMA`).

    The slope ``s = grad P / 2`` and tensor ``[[A + 3 g0 x + g1 y, ...]] / R`` of the model, the
    normal ``sqrt(1 - |s|^2) n + s_1 e1 + s_2 e2`` (exact on a circle) and the tensor carried into
    its tangent plane by the smallest rotation taking ``n`` to it (exact on a sphere).

    ``u`` and ``v`` (shape (3,)) are scratch space: the anchor's frame carried to the point.
    """
    R = radius[a]
    x, y = _tangent_offset(i, a, points, anchors, e1, e2, R)
    c = coefficients[a]
    s1 = 0.5 * (2 * c[0] * x + 2 * c[1] * y + c[3] + 3 * c[5] * x * x + 2 * c[6] * x * y + c[7] * y * y)
    s2 = 0.5 * (2 * c[1] * x + 2 * c[2] * y + c[4] + c[6] * x * x + 2 * c[7] * x * y + 3 * c[8] * y * y)
    slope2 = s1 * s1 + s2 * s2
    if not slope2 < MAX_SLOPE * MAX_SLOPE:  # (also false for nan)
        return False
    up = math.sqrt(1.0 - slope2)
    for k in range(3):
        nrm[k] = up * normals[a, k] + s1 * e1[a, k] + s2 * e2[a, k]
    b11 = (c[0] + 3 * c[5] * x + c[6] * y) / R
    b12 = (c[1] + c[6] * x + c[7] * y) / R
    b22 = (c[2] + c[7] * x + 3 * c[8] * y) / R
    # smallest rotation taking the anchor's normal to the carried one: v -> v + w x v + w x (w x v) / (1 + cos)
    w0 = normals[a, 1] * nrm[2] - normals[a, 2] * nrm[1]
    w1 = normals[a, 2] * nrm[0] - normals[a, 0] * nrm[2]
    w2 = normals[a, 0] * nrm[1] - normals[a, 1] * nrm[0]
    cos = normals[a, 0] * nrm[0] + normals[a, 1] * nrm[1] + normals[a, 2] * nrm[2]
    f = 1.0 / (1.0 + cos)
    for which in range(2):
        src = e1 if which == 0 else e2
        v0, v1, v2 = src[a, 0], src[a, 1], src[a, 2]
        c0 = w1 * v2 - w2 * v1
        c1 = w2 * v0 - w0 * v2
        c2 = w0 * v1 - w1 * v0
        r0 = v0 + c0 + f * (w1 * c2 - w2 * c1)
        r1 = v1 + c1 + f * (w2 * c0 - w0 * c2)
        r2 = v2 + c2 + f * (w0 * c1 - w1 * c0)
        if which == 0:
            frame_u[0], frame_u[1], frame_u[2] = r0, r1, r2
        else:
            frame_v[0], frame_v[1], frame_v[2] = r0, r1, r2
    # T = b11 u u^T + b12 (u v^T + v u^T) + b22 v v^T (u, v: the carried frame), upper triangle
    for t in range(6):
        r, c = _ROW[t], _COL[t]
        tensor[t] = (b11 * frame_u[r] * frame_u[c] + b12 * (frame_u[r] * frame_v[c] + frame_v[r] * frame_u[c])
                     + b22 * frame_v[r] * frame_v[c])
    return True


@njit(**ROW_CORE, inline="always")
def _carry(i, a, points, anchors, normals, e1, e2, coefficients, radius, exact, nrm, tensor, grad, hess, frame_u,
           frame_v):
    """Anchor ``a``'s model at point ``i``: exact (:func:`_carry_one`) unless ``exact[a]`` is 0; False if too steep."""
    if exact[a] != 0.0:
        return _carry_one(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, grad, hess)
    return _carry_first_order(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, frame_u,
                              frame_v)


@njit(**ROW_CORE)
def _carry_anchor_fits(row0, row1, points, indptr, indices, distances, anchors, normals, e1, e2, coefficients,
                       radius, usable, exact, scalars, reference, check, out_n, out_t, out_s, support, total):
    nrm = np.empty(3)
    frame_u = np.empty(3)
    frame_v = np.empty(3)
    tensor = np.empty(6)
    grad = np.empty(3)
    hess = np.empty(6)
    n_scalars = scalars.shape[1]
    for i in range(row0, row1):
        for k in range(3):
            out_n[i, k] = 0.0
        for k in range(6):
            out_t[i, k] = 0.0
        for k in range(n_scalars):
            out_s[i, k] = 0.0
        support[i] = 0.0
        lo, hi = indptr[i], indptr[i + 1]
        d_max = 0.0
        for p in range(lo, hi):
            d_max = max(d_max, distances[p])
        d_max = d_max * (1.0 + 1e-9) + 1e-300
        wsum = 0.0
        best = 0.0
        nearest = -1
        for p in range(lo, hi):
            a = indices[p]
            if usable[a] == 0.0:
                continue
            if nearest < 0:
                nearest = p
            d = distances[p]
            rel = d / d_max
            q = d / radius[a]
            if q >= 1.0:
                continue
            if check:
                agreement = 0.0
                for k in range(3):
                    agreement += normals[a, k] * reference[i, k]
                if agreement < MIN_AGREEMENT:
                    continue
            w = (1.0 - rel * rel) ** 2 * (1.0 - q * q) ** 2
            if w <= 0.0 or not _carry(i, a, points, anchors, normals, e1, e2, coefficients, radius, exact, nrm,
                                      tensor, grad, hess, frame_u, frame_v):
                continue
            wsum += w
            for k in range(3):
                out_n[i, k] += w * nrm[k]
            for k in range(6):
                out_t[i, k] += w * tensor[k]
            if w > best:  # the residual is the most-weighted (nearest) anchor's
                best = w
                out_s[i, 0] = scalars[a, 0]
            for k in range(1, n_scalars):
                out_s[i, k] += w * scalars[a, k]
            support[i] = max(support[i], d + radius[a])
        total[i] = wsum
        if wsum > 0.0:
            for k in range(6):
                out_t[i, k] /= wsum
            for k in range(1, n_scalars):
                out_s[i, k] /= wsum
        elif nearest >= 0:
            # no anchor's ball reaches the point: the nearest usable anchor alone (the caller flags it)
            a = indices[nearest]
            if _carry(i, a, points, anchors, normals, e1, e2, coefficients, radius, exact, nrm, tensor, grad, hess,
                      frame_u, frame_v):
                for k in range(3):
                    out_n[i, k] = nrm[k]
                for k in range(6):
                    out_t[i, k] = tensor[k]
            else:  # too steep even there: the anchor's own normal and tensor, uncarried
                for k in range(3):
                    out_n[i, k] = normals[a, k]
                c = coefficients[a]
                for t in range(6):
                    r, q = _ROW[t], _COL[t]
                    out_t[i, t] = (c[0] * e1[a, r] * e1[a, q] + c[1] * (e1[a, r] * e2[a, q] + e2[a, r] * e1[a, q])
                                   + c[2] * e2[a, r] * e2[a, q]) / radius[a]
            for k in range(n_scalars):
                out_s[i, k] = scalars[a, k]
            support[i] = distances[nearest] + radius[a]
        else:
            for k in range(3):
                out_n[i, k] = math.nan
            for k in range(6):
                out_t[i, k] = math.nan
            for k in range(n_scalars):
                out_s[i, k] = math.nan
            support[i] = math.nan
