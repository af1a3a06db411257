"""Compiled carrying of anchor fits to the points around them (:mod:`heatcurv.fits.anchors`).

Each anchor ``a`` has a chord fit in its frame ``(e1, e2, n)`` with ball radius
``R``: tensor ``(A, B, D)``, tilt ``(t1, t2)``, cubic ``(g0, g1, g2, g3)`` and
optionally quartic ``(q0 .. q4)`` coefficients in units of ``R`` (the columns of
:mod:`heatcurv._kernels.chordfit`). The fit says that a neighbour at tangential
offset ``(x, y)`` (units of ``R``, ``r^2 = x^2 + y^2``) and height ``z`` has the
chord curvature ``kN = -2 z / (r^2 + z^2) = P(x, y) / r^2`` with the polynomial

    P = A x^2 + 2 B x y + D y^2 + t1 x + t2 y + g0 x^3 + g1 x^2 y + g2 x y^2 + g3 y^3
        + q0 x^4 + q1 x^3 y + q2 x^2 y^2 + q3 x y^3 + q4 y^4

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
the model has (the earlier carry was first order in the offset). The point's
values are the weighted means over its nearest anchors, with weights
``(1 - (d / d_max)^2)^2 (1 - (d / R)^2)^2`` (``d_max`` just beyond the row's farthest
anchor): smooth as anchors enter or leave a point's list, zero outside an anchor's ball.

With ``degree`` (very low noise, :func:`heatcurv.fits.anchors.carry_degree`) the tensor is
instead a weighted polynomial regression of the anchors' *own* tensors (their fits at
their centres, rotated into the point's tangent plane by the smallest rotation of
their normals), in the tangent coordinates of the anchors around the point, with the
same weights over all the row's anchors: it reproduces polynomial fields of that
degree, where the mean keeps each model's error away from its centre.

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, as_indices, as_pointers, parallel_rows

__all__ = ["carry_anchor_fits", "MAX_SLOPE", "MIN_AGREEMENT", "REGRESSION_MAX_OFFSET", "REGRESSION_RCOND"]

#: An anchor whose model turns the normal by more than this sine at a point (about 64 degrees)
#: says nothing reliable there: it gets no weight.
MAX_SLOPE = 0.9
#: Least cosine between an anchor's normal and a point's own for the anchor to be carried to it.
MIN_AGREEMENT = 0.5
#: The regression of the anchors' own tensors is refused (the weighted mean instead) where the anchors' weighted
#: centroid is more than this many times the row's farthest anchor distance from the point: anchors on one side
#: (an open border), where the polynomial extrapolates. A point on a straight border has its anchors in a
#: half disc, offset about 0.27 with these weights (0.3 catches corners only); at 0.2 interior points begin to
#: lose the regression (docs/how_it_works.md, thresholds).
REGRESSION_MAX_OFFSET = 0.25
#: Least squared Cholesky pivot, relative to the largest diagonal entry, of a regression's normal
#: matrix (:func:`carry_anchor_fits` with ``degree``): below it the degree is lowered.
REGRESSION_RCOND = 1e-6
# the entries xx, xy, xz, yy, yz, zz of a symmetric 3 x 3 tensor
_ROW = (0, 0, 0, 1, 1, 2)
_COL = (0, 1, 2, 1, 2, 2)


def carry_anchor_fits(points, indptr, indices, distances, anchors, normals, e1, e2, coefficients, radius, usable,
                      scalars, reference=None, n_mean=None, degree=0, exact=None):
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
    coefficients : ndarray, shape (m, 9) or (m, 14)
        Tensor, tilt, cubic and (optionally) quartic coefficients, units of ``radius``.
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
    n_mean : int, optional
        The weighted mean of the carried models uses the first ``n_mean`` anchors of each
        row (the nearest, if the rows are sorted by distance); default all.
    degree : int, optional
        0: the tensor is that mean. 1-3: the tensor is the regression of degree ``degree``
        (lowered where the anchors cannot carry it) of every anchor's own tensor in the row
        (module docstring); the normal stays the mean's.
    exact : ndarray, shape (m,), optional
        1.0 for anchors whose model is carried exactly, 0.0 for those carried to first
        order in the offset (noisy models); default all exactly.

    Returns
    -------
    normals : ndarray, shape (n, 3)
        Weighted sums of the carried unit normals (not normalised).
    tensor : ndarray, shape (n, 6)
        Weighted means of the carried tensors (or the regression's values), ``xx, xy, xz, yy, yz, zz``.
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
    pairs = as_pointers(indptr), as_indices(indices, anchors.shape[0]), as_floats(distances)
    model = (as_floats(anchors), as_floats(normals), as_floats(e1), as_floats(e2), as_floats(coefficients),
             as_floats(radius))
    args = (
        as_floats(points), pairs, model, as_floats(usable),
        np.ones(anchors.shape[0]) if exact is None else as_floats(exact), scalars, reference, check,
        int(np.diff(indptr).max(initial=0)) if n_mean is None else int(n_mean), int(degree),
        (out_n, out_t, out_s, support, total),
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
def _carry_one(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, grad, hess, with_tensor):
    """Anchor ``a``'s normal (into ``nrm``) and tensor (into ``tensor``) at point ``i``; False if too steep.

    The model surface ``F = P (x^2 + y^2 + z^2) + 2 z (x^2 + y^2) = 0`` (module docstring) at the
    point's tangential offset: its unit gradient is the normal and its Hessian, projected onto the
    tangent plane and divided by the gradient's length, the curvature tensor (not computed without
    ``with_tensor``). ``grad`` (shape (3,)) and ``hess`` (shape (6,)) are scratch space.
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
    if c.shape[0] >= 14:  # quartic terms
        P += c[9] * xx * xx + c[10] * xx * xy + c[11] * xx * yy + c[12] * xy * yy + c[13] * yy * yy
        Px += 4 * c[9] * xx * x + 3 * c[10] * xx * y + 2 * c[11] * x * yy + c[12] * yy * y
        Py += c[10] * xx * x + 2 * c[11] * xx * y + 3 * c[12] * x * yy + 4 * c[13] * yy * y
        Pxx += 12 * c[9] * xx + 6 * c[10] * xy + 2 * c[11] * yy
        Pxy += 3 * c[10] * xx + 4 * c[11] * xy + 3 * c[12] * yy
        Pyy += 2 * c[11] * xx + 6 * c[12] * xy + 12 * c[13] * yy
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
    for k in range(3):
        nrm[k] = g0 * e1[a, k] + g1 * e2[a, k] + g2 * normals[a, k]
    if not with_tensor:
        return True
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
    for t in range(6):
        r, s = _ROW[t], _COL[t]
        u0, u1, u2 = e1[a, r], e2[a, r], normals[a, r]
        v0, v1, v2 = e1[a, s], e2[a, s], normals[a, s]
        tensor[t] = (u0 * (t00 * v0 + t01 * v1 + t02 * v2) + u1 * (t01 * v0 + t11 * v1 + t12 * v2)
                     + u2 * (t02 * v0 + t12 * v1 + t22 * v2))
    return True


@njit(**ROW_CORE, inline="always")
def _rotated_frame(a, normals, e1, e2, target, u, v):
    """Anchor ``a``'s tangent frame ``e1, e2`` turned by the smallest rotation taking its normal to ``target``.

    ``x -> x + w x x + w x (w x x) / (1 + cos)`` with ``w = n_a x target``, ``cos = n_a . target``
    (exact on a sphere), into ``u`` and ``v`` (shape (3,)).
    """
    w0 = normals[a, 1] * target[2] - normals[a, 2] * target[1]
    w1 = normals[a, 2] * target[0] - normals[a, 0] * target[2]
    w2 = normals[a, 0] * target[1] - normals[a, 1] * target[0]
    cos = normals[a, 0] * target[0] + normals[a, 1] * target[1] + normals[a, 2] * target[2]
    f = 1.0 / (1.0 + cos)
    for which in range(2):
        src = e1 if which == 0 else e2
        v0, v1, v2 = src[a, 0], src[a, 1], src[a, 2]
        c0 = w1 * v2 - w2 * v1
        c1 = w2 * v0 - w0 * v2
        c2 = w0 * v1 - w1 * v0
        out = u if which == 0 else v
        out[0] = v0 + c0 + f * (w1 * c2 - w2 * c1)
        out[1] = v1 + c1 + f * (w2 * c0 - w0 * c2)
        out[2] = v2 + c2 + f * (w0 * c1 - w1 * c0)


@njit(**ROW_CORE, inline="always")
def _carry_first_order(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, frame_u, frame_v,
                       with_tensor):
    """:func:`_carry_one` to first order in the offset, for noisy models (``TUNING.exact_carry_sigma``).

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
    if not with_tensor:
        return True
    b11 = (c[0] + 3 * c[5] * x + c[6] * y) / R
    b12 = (c[1] + c[6] * x + c[7] * y) / R
    b22 = (c[2] + c[7] * x + 3 * c[8] * y) / R
    _rotated_frame(a, normals, e1, e2, nrm, frame_u, frame_v)
    # T = b11 u u^T + b12 (u v^T + v u^T) + b22 v v^T (u, v: the carried frame), upper triangle
    for t in range(6):
        r, c = _ROW[t], _COL[t]
        tensor[t] = (b11 * frame_u[r] * frame_u[c] + b12 * (frame_u[r] * frame_v[c] + frame_v[r] * frame_u[c])
                     + b22 * frame_v[r] * frame_v[c])
    return True


@njit(**ROW_CORE)
def _carry(i, a, points, model, exact, nrm, tensor, grad, hess, frame_u, frame_v, with_tensor=True):
    """Anchor ``a``'s model at point ``i``: exact (:func:`_carry_one`) unless ``exact[a]`` is 0; False if too steep.

    ``model`` is the anchors' fits: positions, normals, frames ``e1``, ``e2``, coefficients and ball radii.
    Without ``with_tensor`` only the normal (the regression of :func:`_regress_own` gives the tensor).
    """
    anchors, normals, e1, e2, coefficients, radius = model
    if exact[a] != 0.0:
        return _carry_one(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, grad, hess,
                          with_tensor)
    return _carry_first_order(i, a, points, anchors, normals, e1, e2, coefficients, radius, nrm, tensor, frame_u,
                              frame_v, with_tensor)


@njit(**ROW_CORE, inline="always")
def _own_tensor(a, target, frame, normals, e1, e2, coefficients, radius, tensor, u, v):
    """Anchor ``a``'s own tensor (its fit at its centre) rotated into the plane normal to ``target``.

    The rotation is the smallest taking the anchor's normal to ``target`` (shape (3,), unit):
    ``v -> v + w x v + w x (w x v) / (1 + cos)``, exact on a sphere. Into ``tensor`` (shape (3,)):
    its entries ``11, 12, 22`` in the tangent frame ``frame`` of ``target`` (shape (6,): the two
    unit vectors); ``u``, ``v`` (shape (3,)) are scratch space.
    """
    c = coefficients[a]
    b11, b12, b22 = c[0] / radius[a], c[1] / radius[a], c[2] / radius[a]
    _rotated_frame(a, normals, e1, e2, target, u, v)
    # the rotated frame's vectors in the target's frame
    p0 = u[0] * frame[0] + u[1] * frame[1] + u[2] * frame[2]
    p1 = v[0] * frame[0] + v[1] * frame[1] + v[2] * frame[2]
    q0 = u[0] * frame[3] + u[1] * frame[4] + u[2] * frame[5]
    q1 = v[0] * frame[3] + v[1] * frame[4] + v[2] * frame[5]
    tensor[0] = b11 * p0 * p0 + 2.0 * b12 * p0 * p1 + b22 * p1 * p1
    tensor[1] = b11 * p0 * q0 + b12 * (p0 * q1 + p1 * q0) + b22 * p1 * q1
    tensor[2] = b11 * q0 * q0 + 2.0 * b12 * q0 * q1 + b22 * q1 * q1


@njit(**ROW_CORE, inline="always")
def _basis(s, t, phi):
    """The monomials ``1, s, t, s^2, s t, t^2, s^3, s^2 t, s t^2, t^3`` into ``phi`` (shape (10,))."""
    phi[0] = 1.0
    phi[1] = s
    phi[2] = t
    phi[3] = s * s
    phi[4] = s * t
    phi[5] = t * t
    phi[6] = s * s * s
    phi[7] = s * s * t
    phi[8] = s * t * t
    phi[9] = t * t * t


@njit(**ROW_CORE)
def _value_at_zero(G, rhs, m, chol, x, sol):
    """The first row of ``G[:m, :m]^-1 rhs[:m]`` (the fit's value at the point) into ``sol``; False if ill-posed.

    Cholesky of the leading ``m x m`` block (the basis is nested: degree 1, 2, 3 take 3, 6, 10
    monomials); a pivot below :data:`REGRESSION_RCOND` times the block's largest diagonal entry
    (anchors too few or on a line around the point) refuses the degree. ``chol`` (shape (10, 10))
    and ``x`` (shape (10,)) are scratch space.
    """
    top = 0.0
    for a in range(m):
        top = max(top, G[a, a])
    if not top > 0.0:
        return False
    for a in range(m):
        for b in range(a + 1):
            acc = G[a, b]
            for k in range(b):
                acc -= chol[a, k] * chol[b, k]
            if a == b:
                if not acc > REGRESSION_RCOND * top:
                    return False
                chol[a, a] = math.sqrt(acc)
            else:
                chol[a, b] = acc / chol[b, b]
    # solve L L^T x = e_0 for the first row of the inverse, then sol = x^T rhs
    for a in range(m):  # forward: L y = e_0
        acc = 1.0 if a == 0 else 0.0
        for k in range(a):
            acc -= chol[a, k] * x[k]
        x[a] = acc / chol[a, a]
    for a in range(m - 1, -1, -1):  # back: L^T x = y
        acc = x[a]
        for k in range(a + 1, m):
            acc -= chol[k, a] * x[k]
        x[a] = acc / chol[a, a]
    for t in range(sol.shape[0]):
        acc = 0.0
        for a in range(m):
            acc += x[a] * rhs[a, t]
        sol[t] = acc
    return True


@njit(**ROW_CORE, inline="always")
def _anchor_weight(i, p, indices, distances, d_max, radius, usable, normals, reference, check):
    """Weight of the anchor in row slot ``p`` for point ``i``; 0 where it does not count.

    ``(1 - (d / d_max)^2)^2 (1 - (d / R_a)^2)^2``: a taper over the row's nearest anchors times the
    anchor's ball cut (``d`` the point's distance to the anchor, ``R_a`` its ball radius). Unusable
    anchors, points outside the ball and, with ``check``, anchors whose normal is more than 60 degrees
    from the point's ``reference`` normal (:data:`MIN_AGREEMENT`) weigh 0.
    """
    a = indices[p]
    if usable[a] == 0.0:
        return 0.0
    d = distances[p]
    rel = d / d_max
    q = d / radius[a]
    if q >= 1.0:
        return 0.0
    if check:
        agreement = 0.0
        for k in range(3):
            agreement += normals[a, k] * reference[i, k]
        if agreement < MIN_AGREEMENT:
            return 0.0
    return (1.0 - rel * rel) ** 2 * (1.0 - q * q) ** 2


@njit(**ROW_CORE)
def _regress_own(i, lo, hi, points, pairs, model, usable, reference, check, degree, target, out_t, support, scratch):
    """Point ``i``'s tensor as a weighted polynomial regression of its anchors' own tensors; False if ill-posed.

    Each anchor's own tensor is rotated into the plane normal to ``target`` (the point's carried normal)
    and its three entries in that plane are fitted by weighted least squares, in the tangent coordinates of the anchors
    around the point, with polynomials of degree ``degree`` (2 where the anchors cannot carry it; False if
    not even that, or the anchors lie on one side of the point: :data:`REGRESSION_MAX_OFFSET`); the fit's value
    at the point is the tensor. Weights as the mean's, over all the row's anchors.
    ``pairs`` are the rows' anchors and distances, ``model`` as :func:`_carry`; ``scratch`` holds work arrays.
    """
    indices, distances = pairs
    anchors, normals, e1, e2, coefficients, radius = model
    frame, G, rhs, chol, phi, tensor, sol, u, v, xs = scratch
    # a tangent frame of the target normal
    if abs(target[0]) < 0.9:
        ux, uy, uz = 0.0, target[2], -target[1]
    else:
        ux, uy, uz = -target[2], 0.0, target[0]
    length = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / length, uy / length, uz / length
    vx = target[1] * uz - target[2] * uy
    vy = target[2] * ux - target[0] * uz
    vz = target[0] * uy - target[1] * ux
    frame[0], frame[1], frame[2], frame[3], frame[4], frame[5] = ux, uy, uz, vx, vy, vz
    d_max = 0.0
    for p in range(lo, hi):
        d_max = max(d_max, distances[p])
    d_max = d_max * (1.0 + 1e-9) + 1e-300
    G[:, :] = 0.0
    rhs[:, :] = 0.0
    count = 0
    reach = 0.0
    for p in range(lo, hi):
        w = _anchor_weight(i, p, indices, distances, d_max, radius, usable, normals, reference, check)
        if w <= 0.0:
            continue
        a = indices[p]
        d = distances[p]
        _own_tensor(a, target, frame, normals, e1, e2, coefficients, radius, tensor, u, v)
        dx = anchors[a, 0] - points[i, 0]
        dy = anchors[a, 1] - points[i, 1]
        dz = anchors[a, 2] - points[i, 2]
        _basis((dx * ux + dy * uy + dz * uz) / d_max, (dx * vx + dy * vy + dz * vz) / d_max, phi)
        for r in range(10):
            wr = w * phi[r]
            for c in range(r + 1):
                G[r, c] += wr * phi[c]
            for t in range(3):
                rhs[r, t] += wr * tensor[t]
        count += 1
        reach = max(reach, d + radius[a])
    for r in range(10):
        for c in range(r):
            G[c, r] = G[r, c]
    # anchors on one side of the point (an open border): the polynomial would extrapolate; the mean instead
    if G[0, 0] > 0.0 and math.sqrt(G[1, 0] ** 2 + G[2, 0] ** 2) > REGRESSION_MAX_OFFSET * G[0, 0]:
        return False
    # lower the degree while the anchors cannot carry it, but not below 2 (unless asked for 1): a plane fitted
    # through every anchor out to the ball's edge is far worse than the mean of the nearest (a saddle at 1e-5:
    # k1 3.4 % against 0.64 % at the 0.8 % of points that took it); there the caller takes the mean
    for deg in range(degree, min(degree, 2) - 1, -1):
        m = (deg + 1) * (deg + 2) // 2
        # at least twice as many anchors as monomials: a fit through barely enough anchors follows their noise
        if count >= 2 * m and _value_at_zero(G, rhs, m, chol, xs, sol):
            for t in range(6):  # back into the cloud's axes
                r, c = _ROW[t], _COL[t]
                out_t[i, t] = (sol[0] * frame[r] * frame[c] + sol[2] * frame[3 + r] * frame[3 + c]
                               + sol[1] * (frame[r] * frame[3 + c] + frame[3 + r] * frame[c]))
            support[i] = max(support[i], reach)
            return True
    return False


@njit(**ROW_CORE)
def _carry_anchor_fits(row0, row1, points, pairs, model, usable, exact, scalars, reference, check, n_mean, degree,
                       outputs):
    indptr, indices, distances = pairs
    anchors, normals, e1, e2, coefficients, radius = model
    out_n, out_t, out_s, support, total = outputs
    nrm = np.empty(3)
    frame_u = np.empty(3)
    frame_v = np.empty(3)
    tensor = np.empty(6)
    grad = np.empty(3)
    hess = np.empty(6)
    target = np.empty(3)
    frame = np.empty(6)
    own = np.empty(3)
    G = np.empty((10, 10))
    rhs = np.empty((10, 3))
    chol = np.zeros((10, 10))
    phi = np.empty(10)
    sol = np.empty(3)
    xs = np.empty(10)
    with_tensor = degree == 0  # with a regression, the mean's tensor only where the regression is ill-posed
    n_scalars = scalars.shape[1]
    for i in range(row0, row1):
        for k in range(3):
            out_n[i, k] = 0.0
        for k in range(6):
            out_t[i, k] = 0.0
        for k in range(n_scalars):
            out_s[i, k] = 0.0
        support[i] = 0.0
        lo, hi_all = indptr[i], indptr[i + 1]
        hi = min(hi_all, lo + n_mean)  # the nearest n_mean anchors: the weighted mean
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
            w = _anchor_weight(i, p, indices, distances, d_max, radius, usable, normals, reference, check)
            if w <= 0.0 or not _carry(i, a, points, model, exact, nrm, tensor, grad, hess, frame_u, frame_v,
                                      with_tensor):
                continue
            wsum += w
            for k in range(3):
                out_n[i, k] += w * nrm[k]
            if with_tensor:
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
            for k in range(1, n_scalars):
                out_s[i, k] /= wsum
            regressed = False
            if degree > 0:
                length = math.sqrt(out_n[i, 0] ** 2 + out_n[i, 1] ** 2 + out_n[i, 2] ** 2)
                if length > 0.0:
                    for k in range(3):
                        target[k] = out_n[i, k] / length
                    regressed = _regress_own(
                        i, lo, hi_all, points, (indices, distances), model, usable, reference, check, degree, target,
                        out_t, support, (frame, G, rhs, chol, phi, own, sol, frame_u, frame_v, xs),
                    )
                if not regressed:  # the weighted mean of the carried models' tensors, as without a regression
                    for p in range(lo, hi):
                        a = indices[p]
                        w = _anchor_weight(i, p, indices, distances, d_max, radius, usable, normals, reference, check)
                        if w <= 0.0 or not _carry(i, a, points, model, exact, nrm, tensor, grad, hess, frame_u,
                                                  frame_v, True):
                            continue
                        for k in range(6):
                            out_t[i, k] += w * tensor[k]
            if not regressed:
                for k in range(6):
                    out_t[i, k] /= wsum
        elif nearest >= 0:
            # no anchor's ball reaches the point: the nearest usable anchor alone (the caller flags it)
            a = indices[nearest]
            if _carry(i, a, points, model, exact, nrm, tensor, grad, hess, frame_u, frame_v, True):
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
