"""Compiled per-pair work of :func:`heatcurv.fits.chordfit.chord_fit`.

One kernel per fit loops, in parallel over the centres (row cores on threads,
as in :mod:`heatcurv._kernels.segment`), over each centre's CSR
neighbours and accumulates the normal equations directly,

    G_i = sum_j w_ij X_ij X_ij^T,   r_i = sum_j w_ij y_ij X_ij,   (y^T W y)_i,
    G2_i = sum_j w_ij^2 S_ij^2 X_ij X_ij^T   (for the coefficients' covariance under noise),

recomputing everything a pair needs from the points, the centre's frame and
the fitted coefficients; nothing proportional to the number of pairs is
allocated (a numpy formulation with per-pair arrays peaks at about 1 KB per
pair). The normal equations are then solved point by point by Cholesky
(:func:`solve_compiled`, the same ridge and returns as the tests' numpy
reference, ``tests/reference/lstsq.py``; the well-posedness test
brackets the condition number from the traces of ``G`` and ``G^-1`` and
computes eigenvalues only where the bracket cannot decide).

:func:`heatcurv.fits.chordfit.chord_fit` runs the passes (frames, curvatures, the
tilt-corrected normal) around :func:`fit` and :func:`weighted_height_residual`.
An independent numpy reimplementation of the whole fit is
``tests/reference/chordfit.py``; the tests compare the two to 1e-11.

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import numba
import numpy as np

from . import ROW_CORE, as_floats, as_indices, as_pointers, parallel_rows

__all__ = [
    "CHORD",
    "HEIGHT",
    "DENOISED_HEIGHT",
    "LOW_NOISE_HEIGHT",
    "QUARTIC_HEIGHT",
    "LOW_NOISE_MIN_LAMBDA",
    "QUARTIC_COLUMNS",
    "MIN_DOF_FRACTION",
    "WELL_POSED_RCOND",
    "assemble_normal_equations",
    "weighted_height_residual",
    "two_height_residuals",
    "solve_compiled",
    "fit",
    "normal_equations",
]

# What a fit's response and design are:
#: chord curvatures ``kN = -2 z / (r^2 + z^2)`` against the shape columns;
CHORD = 0
#: heights ``z`` against ``[-r^2 / 2 * columns, 1]`` (the plain height fit);
HEIGHT = 1
#: heights ``z`` against ``[-D^2 / 2 * columns, 1]``, ``D^2 = r^2 + (zhat - z0)^2`` from a height fit.
DENOISED_HEIGHT = 2
#: heights ``z`` against ``[-D^2 / 2 * columns, -D^2 / 2 * quartic, 1]``, ``D^2 = r^2 + (zhat - z0)^2`` from a
#: ``QUARTIC_HEIGHT`` fit, pairs weighted ``w lambda^4 / (D^4 + lambda^4)``: the low-noise refit
#: (:func:`heatcurv.fits.chordfit.chord_fit`);
LOW_NOISE_HEIGHT = 3
#: heights ``z`` against ``[-r^2 / 2 * columns, -r^2 / 2 * quartic, 1]`` (the height fit with quartic terms).
QUARTIC_HEIGHT = 4
#: Quartic columns of the low-noise refit: ``r^2 c^4, r^2 c^3 s, r^2 c^2 s^2, r^2 c s^3, r^2 s^4``.
QUARTIC_COLUMNS = 5
#: Least ``lambda`` of the low-noise refit, units of the ball radius: on a clean ball ``lambda -> 0`` and the
#: weights ``1 / D^4`` of far pairs against ``1`` of a pair at the centre (``D = 0``) made the normal equations
#: singular to rounding (a grid under a saddle: the numpy and compiled fits 7e-7 apart). The floor only acts
#: where ``sigma`` is below ``TUNING.low_noise_sigma * 0.05^2 = 1.5e-6`` ball radii (noise 1e-5 of a torus's
#: diagonal at 480 neighbours is 1.7e-4).
LOW_NOISE_MIN_LAMBDA = 0.05

#: Floor of ``1 - p / n_eff`` in the residual variance (balls barely larger than the model);
#: see :func:`_unbiased_mean_square`.
MIN_DOF_FRACTION = 0.1


@numba.njit(cache=True)
def _local_coordinates(points, centres, i, j, e1, e2, normals, inverse_unit):
    """Neighbour ``j`` in centre ``i``'s frame ``(e1, e2, n)``, times ``inverse_unit`` (1 / the length unit)."""
    d0 = points[j, 0] - centres[i, 0]
    d1 = points[j, 1] - centres[i, 1]
    d2 = points[j, 2] - centres[i, 2]
    x = (d0 * e1[i, 0] + d1 * e1[i, 1] + d2 * e1[i, 2]) * inverse_unit
    y = (d0 * e2[i, 0] + d1 * e2[i, 1] + d2 * e2[i, 2]) * inverse_unit
    z = (d0 * normals[i, 0] + d1 * normals[i, 1] + d2 * normals[i, 2]) * inverse_unit
    return x, y, z


@numba.njit(cache=True)
def _fill_shape_columns(x, y, tilt, cubic, cols):
    """One pair's kN model columns into ``cols``; returns ``r^2 = x^2 + y^2``.

    The order :func:`heatcurv.fits.chordfit.chord_fit`'s coefficients follow: tensor
    ``c^2, 2 c s, s^2``, tilt ``c / r, s / r``, cubic ``r c^3, r c^2 s, r c s^2, r s^3``
    (``c, s = x / r, y / r``). Each column is a monomial over ``r^2``
    (``c^2 = x^2 / r^2``, ``c / r = x / r^2``, ``r c^3 = x^3 / r^2`` ...): one
    division and no square root per pair (the same columns to rounding; the
    square root and four divisions of the literal formulas took half the
    assembly's time).
    """
    xx, xy, yy = x * x, x * y, y * y
    r2 = xx + yy
    if r2 > 0:
        inv = 1.0 / r2
    else:  # the neighbour straight above the centre: direction (1, 0) by convention, as if r = 1
        xx, xy, yy, x, y, inv = 1.0, 0.0, 0.0, 1.0, 0.0, 1.0
    cols[0] = xx * inv
    cols[1] = 2 * xy * inv
    cols[2] = yy * inv
    k = 3
    if tilt:
        cols[3] = x * inv
        cols[4] = y * inv
        k = 5
    if cubic:
        if r2 > 0:
            cols[k] = x * xx * inv
            cols[k + 1] = xx * y * inv
            cols[k + 2] = x * yy * inv
            cols[k + 3] = y * yy * inv
        else:  # r c^3 ... at r = 0
            cols[k] = cols[k + 1] = cols[k + 2] = cols[k + 3] = 0.0
    return r2


@numba.njit(cache=True)
def _fill_quartic_columns(x, y, r2, X, first):
    """The quartic columns ``r^2 c^4 ... r^2 s^4`` (``x^4 / r^2 ...``) into ``X[first:first + 5]``."""
    if r2 > 0:
        inv = 1.0 / r2
        xx, yy = x * x, y * y
        X[first] = xx * xx * inv
        X[first + 1] = xx * x * y * inv
        X[first + 2] = xx * yy * inv
        X[first + 3] = x * y * yy * inv
        X[first + 4] = yy * yy * inv
    else:
        for a in range(QUARTIC_COLUMNS):
            X[first + a] = 0.0


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def _gram(At, m, out):
    """``out = At[:, :m] At[:, :m]^T``, symmetric: the upper triangle's dot products over the pairs, mirrored.

    Reassociation lets the compiler vectorise each dot product (summed in
    another order than pair by pair: a difference of rounding); four of them
    share each load of row ``a``. Measured 3x faster than a BLAS ``dgemm``
    per centre, whose call overhead dominates at these sizes (60 x 9).
    """
    p = At.shape[0]
    for a in range(p):
        b = a
        while b + 4 <= p:
            s0 = s1 = s2 = s3 = 0.0
            for t in range(m):
                u = At[a, t]
                s0 += u * At[b, t]
                s1 += u * At[b + 1, t]
                s2 += u * At[b + 2, t]
                s3 += u * At[b + 3, t]
            out[a, b], out[a, b + 1], out[a, b + 2], out[a, b + 3] = s0, s1, s2, s3
            b += 4
        for c in range(b, p):
            s = 0.0
            for t in range(m):
                s += At[a, t] * At[c, t]
            out[a, c] = s
        for c in range(a + 1, p):
            out[c, a] = out[a, c]


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def _times(At, v, m, out):
    """``out = At[:, :m] v[:m]`` (as :func:`_gram`, vectorised)."""
    for a in range(At.shape[0]):
        s = 0.0
        for t in range(m):
            s += At[a, t] * v[t]
        out[a] = s


@numba.njit(cache=True)
def _denoised_denominator(cols, n_shape, r2, height_beta, i):
    """``D^2 = r^2 + (zhat - z0)^2`` with ``zhat`` the plain height fit ``height_beta[i]`` at the pair."""
    # zhat = [-r^2/2 * cols, 1] . beta, the constant column last (as the numpy reference sums it)
    zhat = 0.0
    for a in range(n_shape):
        zhat += -0.5 * r2 * cols[a] * height_beta[i, a]
    z0 = height_beta[i, n_shape]
    zhat += z0
    dz = zhat - z0
    return r2 + dz * dz


@numba.njit(cache=True)
def _quartic_denominator(cols, quartic, n_shape, r2, height_beta, i):
    """``D^2 = r^2 + (zhat - z0)^2`` with ``zhat`` the ``QUARTIC_HEIGHT`` fit ``height_beta[i]`` at the pair."""
    dz = 0.0
    for a in range(n_shape):
        dz += -0.5 * r2 * cols[a] * height_beta[i, a]
    for a in range(QUARTIC_COLUMNS):
        dz += -0.5 * r2 * quartic[a] * height_beta[i, n_shape + a]
    return r2 + dz * dz


def assemble_normal_equations(
    points, centres, indptr, indices, weights, unit, normals, e1, e2, tilt, cubic, kind, height_beta, G, rhs, yy, G2
):
    """Accumulate every centre's weighted normal equations over its neighbours.

    Parameters
    ----------
    points, centres : ndarray, shape (N, 3), (n, 3)
    indptr, indices : ndarray
        CSR neighbours of the centres.
    weights : ndarray, shape (nnz,)
    unit : ndarray, shape (n,)
        Each centre's ball radius.
    normals, e1, e2 : ndarray, shape (n, 3)
        Each centre's frame.
    tilt, cubic : bool
    kind : int
        ``CHORD``, ``HEIGHT``, ``DENOISED_HEIGHT``, ``LOW_NOISE_HEIGHT`` or ``QUARTIC_HEIGHT``.
    height_beta : ndarray, shape (n, p) or (0, p)
        The plain height fit (for ``DENOISED_HEIGHT``), or for ``LOW_NOISE_HEIGHT`` the
        ``QUARTIC_HEIGHT`` fit and one more column, last: each centre's ``lambda^4``
        (units of ``unit``).
    G, rhs, yy : ndarray, shape (n, p, p), (n, p), (n,)
        Output: ``X^T W X``, ``X^T W y``, ``y^T W y``.
    G2 : ndarray, shape (n, p, p) or (0, p, p)
        Output if not empty: ``X^T W^2 S^2 X`` with ``S`` the response noise per
        unit height noise (``2 / D^2`` for chord curvatures, 1 for heights).
    """
    points, indptr = as_floats(points), as_pointers(indptr)
    geometry = (points, as_floats(centres), indptr, as_indices(indices, points.shape[0]), as_floats(weights),
                as_floats(unit), as_floats(normals), as_floats(e1), as_floats(e2))
    args = geometry, bool(tilt), bool(cubic), int(kind)
    core = _assemble_full_model if tilt and cubic else _assemble_normal_equations
    parallel_rows(core, indptr.shape[0] - 1, *args, as_floats(height_beta), G, rhs, yy, G2)


@numba.njit(**ROW_CORE)
def _assemble_normal_equations(row0, row1, geometry, tilt, cubic, kind, height_beta, G, rhs, yy, G2):
    _assemble_rows(row0, row1, geometry, tilt, cubic, kind, height_beta, G, rhs, yy, G2)


@numba.njit(**ROW_CORE)
def _assemble_full_model(row0, row1, geometry, tilt, cubic, kind, height_beta, G, rhs, yy, G2):
    # the full model (tilt and cubic terms, every fit the estimator runs): with the flags constants
    # the compiler drops their branches and fixes the columns' places (1.5x faster than the general
    # core, which compiles only when a fit without them runs)
    _assemble_rows(row0, row1, geometry, True, True, kind, height_beta, G, rhs, yy, G2)


@numba.njit(cache=True, inline="always")
def _assemble_rows(row0, row1, geometry, tilt, cubic, kind, height_beta, G, rhs, yy, G2):
    points, centres, indptr, indices, weights, unit, normals, e1, e2 = geometry
    p = rhs.shape[1]
    n_shape = 3 + 2 * tilt + 4 * cubic
    with_g2 = G2.shape[0] > 0
    longest = 0
    for i in range(row0, row1):
        longest = max(longest, indptr[i + 1] - indptr[i])
    cols = np.empty(n_shape)
    X = np.empty(p)
    # the columns sqrt(w) X_ij (and w S_ij X_ij) of one centre, pair by pair: the sums are then
    # dot products of these rows, G = A^T A (_gram)
    At = np.empty((p, longest))
    b = np.empty(longest)
    St = np.empty((p if with_g2 else 0, longest))
    for i in range(row0, row1):
        lo, hi = indptr[i], indptr[i + 1]
        m = hi - lo
        inverse_unit = 1.0 / unit[i]
        yyi = 0.0
        for t in range(m):
            k = lo + t
            x, y, z = _local_coordinates(points, centres, i, indices[k], e1, e2, normals, inverse_unit)
            r2 = _fill_shape_columns(x, y, tilt, cubic, cols)
            if kind == CHORD:
                D2 = r2 + z * z
                if D2 > 0:
                    # a height error eps moves kN by 2 eps / D^2
                    noise = 2.0 / D2
                    response = -z * noise
                else:
                    response = 0.0
                    noise = 0.0
                for a in range(p):
                    X[a] = cols[a]
            else:
                D2 = r2  # HEIGHT, QUARTIC_HEIGHT
                if kind == DENOISED_HEIGHT:
                    D2 = _denoised_denominator(cols, n_shape, r2, height_beta, i)
                if kind == LOW_NOISE_HEIGHT or kind == QUARTIC_HEIGHT:
                    _fill_quartic_columns(x, y, r2, X, n_shape)
                    if kind == LOW_NOISE_HEIGHT:
                        D2 = _quartic_denominator(cols, X[n_shape:], n_shape, r2, height_beta, i)
                    for a in range(n_shape, p - 1):
                        X[a] *= -0.5 * D2
                for a in range(n_shape):
                    X[a] = -0.5 * D2 * cols[a]
                X[p - 1] = 1.0
                response = z
                noise = 1.0
            w = weights[k]
            if kind == LOW_NOISE_HEIGHT:
                # near pairs weigh as in the chord fit (1 / D^4 on heights), far ones as in the height fit
                lam4 = height_beta[i, n_shape + QUARTIC_COLUMNS + 1]
                w *= lam4 / (D2 * D2 + lam4)
            yyi += w * response * response
            sw = np.sqrt(w)
            for a in range(p):
                At[a, t] = sw * X[a]
            b[t] = sw * response
            if with_g2:
                sn = w * noise
                for a in range(p):
                    St[a, t] = sn * X[a]
        _gram(At, m, G[i])
        _times(At, b, m, rhs[i])
        if with_g2:
            _gram(St, m, G2[i])
        yy[i] = yyi


def two_height_residuals(
    points, centres, indptr, indices, weights, unit, normals, e1, e2, tilt, cubic, plain, quartic, sigma2_plain,
    sigma2_quartic
):
    """:func:`weighted_height_residual` of two height fits in one pass over the pairs.

    ``plain`` (shape (n, n_shape + 1)) is a ``HEIGHT`` fit, ``quartic`` (shape (n, n_shape + 6))
    a ``QUARTIC_HEIGHT`` fit; their residuals go into ``sigma2_plain`` and ``sigma2_quartic``, the
    same numbers as two calls of :func:`weighted_height_residual` (the low-noise refit reads both).
    """
    points, indptr = as_floats(points), as_pointers(indptr)
    geometry = (points, as_floats(centres), indptr, as_indices(indices, points.shape[0]), as_floats(weights),
                as_floats(unit), as_floats(normals), as_floats(e1), as_floats(e2))
    args = geometry, bool(tilt), bool(cubic)
    args += as_floats(plain), as_floats(quartic), sigma2_plain, sigma2_quartic
    core = _two_residuals_full_model if tilt and cubic else _two_height_residuals
    parallel_rows(core, indptr.shape[0] - 1, *args)


@numba.njit(**ROW_CORE)
def _two_height_residuals(row0, row1, geometry, tilt, cubic, plain, quartic, sigma2_plain, sigma2_quartic):
    _two_residual_rows(row0, row1, geometry, tilt, cubic, plain, quartic, sigma2_plain, sigma2_quartic)


@numba.njit(**ROW_CORE)
def _two_residuals_full_model(row0, row1, geometry, tilt, cubic, plain, quartic, sigma2_plain, sigma2_quartic):
    # the full model's flags as constants (as _assemble_full_model)
    _two_residual_rows(row0, row1, geometry, True, True, plain, quartic, sigma2_plain, sigma2_quartic)


@numba.njit(cache=True, inline="always")
def _two_residual_rows(row0, row1, geometry, tilt, cubic, plain, quartic, sigma2_plain, sigma2_quartic):
    points, centres, indptr, indices, weights, unit, normals, e1, e2 = geometry
    p = plain.shape[1]
    width = quartic.shape[1]
    n_shape = 3 + 2 * tilt + 4 * cubic
    cols = np.empty(n_shape)
    extra = np.empty(n_shape + QUARTIC_COLUMNS)
    for i in range(row0, row1):
        sq_plain = 0.0
        sq_quartic = 0.0
        total_weight = 0.0
        total_sq_weight = 0.0
        inverse_unit = 1.0 / unit[i]
        for k in range(indptr[i], indptr[i + 1]):
            x, y, z = _local_coordinates(points, centres, i, indices[k], e1, e2, normals, inverse_unit)
            r2 = _fill_shape_columns(x, y, tilt, cubic, cols)
            _fill_quartic_columns(x, y, r2, extra, n_shape)
            fitted_plain = 0.0
            fitted_quartic = 0.0
            for a in range(n_shape):
                fitted_plain += -0.5 * r2 * cols[a] * plain[i, a]
                fitted_quartic += -0.5 * r2 * cols[a] * quartic[i, a]
            for a in range(QUARTIC_COLUMNS):
                fitted_quartic += -0.5 * r2 * extra[n_shape + a] * quartic[i, n_shape + a]
            fitted_plain += plain[i, p - 1]
            fitted_quartic += quartic[i, width - 1]
            w = weights[k]
            resid = z - fitted_plain
            sq_plain += w * resid * resid
            resid = z - fitted_quartic
            sq_quartic += w * resid * resid
            total_weight += w
            total_sq_weight += w * w
        sigma2_plain[i] = _unbiased_mean_square(sq_plain, total_weight, total_sq_weight, p)
        sigma2_quartic[i] = _unbiased_mean_square(sq_quartic, total_weight, total_sq_weight, width)


@numba.njit(cache=True)
def _unbiased_mean_square(weighted_sq, total_weight, total_sq_weight, p):
    """Noise variance from one centre's weighted residuals, corrected for the degrees of freedom the fit used.

    ``sum_j w_j r_j^2 / sum_j w_j`` underestimates the noise variance: a fit
    with ``p`` coefficients absorbs part of the noise. With leverages about
    proportional to the weights its expectation is ``sigma^2 (1 - p / n_eff)``,
    ``n_eff = (sum w)^2 / sum w^2`` the effective number of neighbours, so
    that factor is divided out (floored at :data:`MIN_DOF_FRACTION`). With
    60 neighbours under the tapered heat kernel ``n_eff`` is about 25, and
    the uncorrected estimate was low by about 1.3x: enough to make the
    kernel choice stop early on dense noisy clouds.
    """
    mean_sq = weighted_sq / max(total_weight, 1e-300)
    n_eff = total_weight * total_weight / max(total_sq_weight, 1e-300)
    if n_eff <= p:  # (also no neighbours at all: n_eff = 0)
        return mean_sq / MIN_DOF_FRACTION
    return mean_sq / max(1.0 - p / n_eff, MIN_DOF_FRACTION)


def weighted_height_residual(
    points, centres, indptr, indices, weights, unit, normals, e1, e2, tilt, cubic, kind, height_beta, beta, sigma2
):
    """Weighted mean square height residual of each centre's final fit, into ``sigma2``.

    ``kind`` is ``CHORD`` (a kN residual, times ``D^2 / 2`` to make it a height),
    ``HEIGHT`` or ``QUARTIC_HEIGHT`` (``beta`` the height fit itself), ``DENOISED_HEIGHT``
    or ``LOW_NOISE_HEIGHT`` (``beta`` the refit of ``height_beta``, residuals weighted
    ``w`` alone); other
    arguments as :func:`assemble_normal_equations`. Units of ``unit``.
    """
    points, indptr = as_floats(points), as_pointers(indptr)
    geometry = (points, as_floats(centres), indptr, as_indices(indices, points.shape[0]), as_floats(weights),
                as_floats(unit), as_floats(normals), as_floats(e1), as_floats(e2))
    args = geometry, bool(tilt), bool(cubic), int(kind)
    args += as_floats(height_beta), as_floats(beta), sigma2
    core = _residual_full_model if tilt and cubic else _weighted_height_residual
    parallel_rows(core, indptr.shape[0] - 1, *args)


@numba.njit(**ROW_CORE)
def _weighted_height_residual(row0, row1, geometry, tilt, cubic, kind, height_beta, beta, sigma2):
    _residual_rows(row0, row1, geometry, tilt, cubic, kind, height_beta, beta, sigma2)


@numba.njit(**ROW_CORE)
def _residual_full_model(row0, row1, geometry, tilt, cubic, kind, height_beta, beta, sigma2):
    # the full model's flags as constants (as _assemble_full_model)
    _residual_rows(row0, row1, geometry, True, True, kind, height_beta, beta, sigma2)


@numba.njit(cache=True, inline="always")
def _residual_rows(row0, row1, geometry, tilt, cubic, kind, height_beta, beta, sigma2):
    points, centres, indptr, indices, weights, unit, normals, e1, e2 = geometry
    p = beta.shape[1]
    n_shape = 3 + 2 * tilt + 4 * cubic
    cols = np.empty(n_shape)
    # (filled from n_shape on, as the design row of _assemble_rows: one compiled signature of the helpers)
    quartic = np.empty(n_shape + QUARTIC_COLUMNS)
    for i in range(row0, row1):
        weighted_sq = 0.0
        total_weight = 0.0
        total_sq_weight = 0.0
        inverse_unit = 1.0 / unit[i]
        for k in range(indptr[i], indptr[i + 1]):
            x, y, z = _local_coordinates(points, centres, i, indices[k], e1, e2, normals, inverse_unit)
            r2 = _fill_shape_columns(x, y, tilt, cubic, cols)
            if kind == CHORD:
                D2 = r2 + z * z
                kN = -z * (2.0 / D2) if D2 > 0 else 0.0  # as the fit's response
                fitted = 0.0
                for a in range(p):
                    fitted += cols[a] * beta[i, a]
                resid = (kN - fitted) * D2 / 2
            else:
                D2 = r2  # HEIGHT, QUARTIC_HEIGHT
                if kind == DENOISED_HEIGHT:
                    D2 = _denoised_denominator(cols, n_shape, r2, height_beta, i)
                if kind == LOW_NOISE_HEIGHT or kind == QUARTIC_HEIGHT:
                    _fill_quartic_columns(x, y, r2, quartic, n_shape)
                    if kind == LOW_NOISE_HEIGHT:
                        D2 = _quartic_denominator(cols, quartic[n_shape:], n_shape, r2, height_beta, i)
                fitted = 0.0
                for a in range(n_shape):
                    fitted += -0.5 * D2 * cols[a] * beta[i, a]
                if kind == LOW_NOISE_HEIGHT or kind == QUARTIC_HEIGHT:
                    for a in range(QUARTIC_COLUMNS):
                        fitted += -0.5 * D2 * quartic[n_shape + a] * beta[i, n_shape + a]
                fitted += beta[i, p - 1]
                resid = z - fitted
            w = weights[k]
            weighted_sq += w * resid * resid
            total_weight += w
            total_sq_weight += w * w
        sigma2[i] = _unbiased_mean_square(weighted_sq, total_weight, total_sq_weight, p)


@numba.njit(cache=True)
def _cholesky(A, L):
    """Lower Cholesky factor of the symmetric ``A`` into ``L``; False if ``A`` is not positive definite."""
    p = A.shape[0]
    for j in range(p):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, p):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
        for i in range(j):
            L[i, j] = 0.0
    return True


@numba.njit(cache=True)
def _cholesky_solve(L, b, x):
    """Solve ``L L^T x = b``."""
    p = L.shape[0]
    for i in range(p):
        t = b[i]
        for k in range(i):
            t -= L[i, k] * x[k]
        x[i] = t / L[i, i]
    for i in range(p - 1, -1, -1):
        t = x[i]
        for k in range(i + 1, p):
            t -= L[k, i] * x[k]
        x[i] = t / L[i, i]


@numba.njit(cache=True)
def _trace_of_inverse(L, work):
    """``trace((L L^T)^-1) = ||L^-1||_F^2``, column by column of ``L^-1``."""
    p = L.shape[0]
    total = 0.0
    for c in range(p):
        for i in range(p):
            t = 1.0 if i == c else 0.0
            for k in range(c, i):
                t -= L[i, k] * work[k]
            work[i] = t / L[i, i] if i >= c else 0.0
            if i >= c:
                total += work[i] * work[i]
    return total


#: ``well_posed`` is ``lambda_min(G) > WELL_POSED_RCOND lambda_max(G)`` (as in the tests' numpy reference).
WELL_POSED_RCOND = 1e-10


@numba.njit(**ROW_CORE)
def _solve_normal_equations(row0, row1, G, rhs, yy, ridge, jacobi, contrast, G2, with_variance, check, outputs):
    """:func:`solve_compiled` for the points ``row0 <= i < row1``, by Cholesky.

    ``posed`` gets 1 (well posed), 0 (ill posed) or -1 (undecided: the caller
    checks those few points by their eigenvalues). The condition number
    ``kappa = lambda_max / lambda_min`` is bracketed without eigenvalues:
    ``kappa <= trace(G) trace(G^-1) <= p^2 kappa``.
    """
    beta, rss, posed, variance = outputs
    p = rhs.shape[1]
    n_contrasts = contrast.shape[0]
    A = np.empty((p, p))  # (work arrays allocated once per range of rows, as in every core)
    L = np.empty((p, p))
    work = np.empty(p)
    x = np.empty(p)
    U = np.empty((n_contrasts, p))
    for i in range(row0, row1):
        trace = 0.0
        for a in range(p):
            trace += G[i, a, a]
        scale = max(trace / p, 1e-300)
        for a in range(p):
            for b in range(p):
                A[a, b] = G[i, a, b]
            A[a, a] += ridge * (G[i, a, a] if jacobi and G[i, a, a] > 0.0 else scale)
        if _cholesky(A, L):
            _cholesky_solve(L, rhs[i], x)
        else:  # not reached for a positive semi-definite G; keep a finite answer
            for a in range(p):
                x[a] = 0.0
        fitted_sq = 0.0
        cross = 0.0
        for a in range(p):
            beta[i, a] = x[a]
            cross += x[a] * rhs[i, a]
            t = 0.0
            for b in range(p):
                t += G[i, a, b] * x[b]
            fitted_sq += x[a] * t
        rss[i] = max(yy[i] - 2.0 * cross + fitted_sq, 0.0)
        if with_variance:
            # u_c = G^-1 c for each contrast c, then Cov = U G2 U^T
            for c in range(n_contrasts):
                _cholesky_solve(L, contrast[c], x)
                for a in range(p):
                    U[c, a] = x[a]
            for c in range(n_contrasts):
                for a in range(p):
                    t = 0.0
                    for b in range(p):
                        t += G2[i, a, b] * U[c, b]
                    work[a] = t
                for e in range(c + 1):
                    v = 0.0
                    for a in range(p):
                        v += U[e, a] * work[a]
                    variance[i, c, e] = v
                    variance[i, e, c] = v
        if not check:  # a pass before the last: only its coefficients are used
            posed[i] = 1
            continue
        # well posed? bracket the condition number of the unregularised G
        for a in range(p):
            for b in range(p):
                A[a, b] = G[i, a, b]
        if trace <= 0.0 or not _cholesky(A, L):
            posed[i] = 0 if trace <= 0.0 else -1
            continue
        bound = trace * _trace_of_inverse(L, work)
        if bound * WELL_POSED_RCOND < 1.0:
            posed[i] = 1
        elif bound * WELL_POSED_RCOND > p * p:
            posed[i] = 0
        else:
            posed[i] = -1


def solve_compiled(G, rhs, yy, ridge=1e-10, contrast=None, G2=None, check=True, jacobi=False):
    """Every point's weighted normal equations ``G beta = rhs`` solved by Cholesky, compiled.

    Same ridge and returns as the numpy ``solve_normal_equations`` of ``tests/reference/lstsq.py``.
    ``contrast``, shape (p,) or (c, p): with ``G2``, the variance factor ``c^T G^-1 G2 G^-1 c`` of
    one contrast (``variance`` of shape (n,)), or the covariance factors ``C G^-1 G2 G^-1 C^T`` of
    several (shape (n, c, c)), with ``G^-1`` the regularised inverse.

    The ridge solve by Cholesky instead of LU agrees to rounding; ``well_posed``
    is exact (eigenvalues are computed for the points the bracket leaves
    undecided). ``check=False`` skips the well-posedness test (all True) for
    fits whose coefficients alone are used. ``jacobi``: the ridge relative to each
    diagonal entry (``ridge_solve`` of ``tests/reference/lstsq.py``).
    """
    G, rhs, yy = as_floats(G), as_floats(rhs), as_floats(yy)
    n, p = rhs.shape
    c = np.zeros((1, p)) if contrast is None else np.atleast_2d(as_floats(contrast))
    beta, rss = np.empty((n, p)), np.empty(n)
    variance = np.empty((n if contrast is not None else 0, c.shape[0], c.shape[0]))
    posed = np.empty(n, dtype=np.int8)
    g2 = as_floats(G2) if contrast is not None else np.empty((0, p, p))
    outputs = beta, rss, posed, variance
    args = G, rhs, yy, float(ridge), bool(jacobi), c, g2, contrast is not None, bool(check), outputs
    parallel_rows(_solve_normal_equations, n, *args)
    well_posed = posed == 1
    undecided = np.flatnonzero(posed < 0)
    if undecided.size:
        evals = np.linalg.eigvalsh(G[undecided])
        well_posed[undecided] = evals[:, 0] > WELL_POSED_RCOND * np.maximum(evals[:, -1], 1e-300)
    if contrast is None:
        return beta, rss, well_posed
    return beta, rss, well_posed, variance[:, 0, 0] if np.ndim(contrast) == 1 else variance


def normal_equations(kind, p, geometry, height_beta=None):
    """The normal equations ``G, rhs, yy`` of one fit (:func:`assemble_normal_equations`, no ``G2``), unsolved.

    The low-noise refit solves the plain height fit from the ``QUARTIC_HEIGHT`` equations' block of
    its columns (the same sums, to the bit) instead of assembling it again.
    """
    n = geometry[2].shape[0] - 1
    G = np.empty((n, p, p))
    rhs = np.empty((n, p))
    yy = np.empty(n)
    if height_beta is None:
        height_beta = np.empty((0, p))
    assemble_normal_equations(*geometry, kind, height_beta, G, rhs, yy, np.empty((0, p, p)))
    return G, rhs, yy


def fit(kind, p, geometry, height_beta=None, contrast=None):
    """Assemble one fit with :func:`assemble_normal_equations` and solve it.

    Parameters
    ----------
    kind : int
        ``CHORD``, ``HEIGHT``, ``DENOISED_HEIGHT``, ``LOW_NOISE_HEIGHT`` or ``QUARTIC_HEIGHT``.
    p : int
        Unknowns of the fit.
    geometry : tuple
        ``(points, centres, indptr, indices, weights, unit, normals, e1, e2, tilt, cubic)``
        as :func:`assemble_normal_equations` takes them.
    height_beta : ndarray, shape (n, p), optional
        The plain height fit (``DENOISED_HEIGHT`` and ``LOW_NOISE_HEIGHT``; see
        :func:`assemble_normal_equations`).
    contrast : ndarray, shape (p,) or (c, p), optional
        Given for the final fit (the last pass's, whose diagnostics are
        reported): it is solved by :func:`solve_compiled` with these contrasts
        and returns ``beta, rss, well_posed, variance`` (the covariance factors of
        several contrasts: shape (n, c, c)). Without it the fit
        only passes its coefficients on, skips ``G2`` and the
        well-posedness test, and returns ``beta`` alone.
    """
    final = contrast is not None
    indptr = geometry[2]
    n = indptr.shape[0] - 1
    G = np.empty((n, p, p))
    rhs = np.empty((n, p))
    yy = np.empty(n)
    G2 = np.empty((n if final else 0, p, p))
    if height_beta is None:
        height_beta = np.empty((0, p))
    assemble_normal_equations(*geometry, kind, height_beta, G, rhs, yy, G2)
    # the quartic fits' columns span many orders of magnitude (r^4 terms against the offset): a ridge
    # relative to the trace pulled their small columns' coefficients, by an amount that depends on the
    # tangent frame's in-plane turn (a clean 663-point paraboloid, rotated: k2 1.4e-5 of the largest
    # curvature apart; relative to each diagonal entry: 3e-7)
    jacobi = kind == LOW_NOISE_HEIGHT or kind == QUARTIC_HEIGHT
    if not final:
        return solve_compiled(G, rhs, yy, check=False, jacobi=jacobi)[0]
    return solve_compiled(G, rhs, yy, contrast=contrast, G2=G2, jacobi=jacobi)
