"""Compiled per-pair work of :func:`heatcurv.chordfit.chord_fit` (numba).

The numpy path of :func:`heatcurv.chordfit.chord_fit` builds per-pair arrays
(local coordinates, model columns, responses, then padded blocks for the
batched products): about 1 KB per pair at its peak. Here one kernel per fit
loops, in parallel over the centres, over each centre's CSR neighbours and
accumulates the normal equations directly,

    G_i = sum_j w_ij X_ij X_ij^T,   r_i = sum_j w_ij y_ij X_ij,   (y^T W y)_i,
    G2_i = sum_j w_ij^2 S_ij^2 X_ij X_ij^T   (for the variance of the mean),

recomputing everything a pair needs from the points, the centre's frame and
the fitted coefficients; nothing proportional to the number of pairs is
allocated. The solve and everything after it are the numpy path's own
functions (:func:`heatcurv.chordfit.solve_normal_equations` and the pass
helpers), so both paths differ only by the order of the floating-point sums.

Only :func:`heatcurv.chordfit.chord_fit` imports this module, and only when
:func:`heatcurv.backend.use_numba` is true.
"""

from __future__ import annotations

import numba
import numpy as np

from .chordfit import (
    ChordFit,
    _chord_fit_result,
    _mean_contrast,
    _principal_and_refined_normal,
    ridge_solve,
    solve_normal_equations,
)
from .neighbourhood import Neighbourhood
from .normals import tangent_frames

__all__ = ["chord_fit_compiled"]

# What a fit's response and design are (the numpy path's three calls of segment_lstsq):
#: chord curvatures ``kN = -2 z / (r^2 + z^2)`` against the shape columns;
_CHORD = 0
#: heights ``z`` against ``[-r^2 / 2 * columns, 1]`` (the plain height fit);
_HEIGHT = 1
#: heights ``z`` against ``[-D^2 / 2 * columns, 1]``, ``D^2 = r^2 + (zhat - z0)^2`` from a height fit.
_DENOISED_HEIGHT = 2


@numba.njit(cache=True)
def _local_coordinates(points, centres, i, j, e1, e2, normals, unit):
    """Neighbour ``j`` in centre ``i``'s frame ``(e1, e2, n)``, in units of ``unit``."""
    d0 = points[j, 0] - centres[i, 0]
    d1 = points[j, 1] - centres[i, 1]
    d2 = points[j, 2] - centres[i, 2]
    x = (d0 * e1[i, 0] + d1 * e1[i, 1] + d2 * e1[i, 2]) / unit
    y = (d0 * e2[i, 0] + d1 * e2[i, 1] + d2 * e2[i, 2]) / unit
    z = (d0 * normals[i, 0] + d1 * normals[i, 1] + d2 * normals[i, 2]) / unit
    return x, y, z


@numba.njit(cache=True)
def _fill_shape_columns(x, y, tilt, cubic, cols):
    """One pair's kN model columns (as ``_shape_columns``) into ``cols``; returns ``r``."""
    r = np.sqrt(x * x + y * y)
    if r > 0:
        safe, c, s = r, x / r, y / r
    else:  # the neighbour straight above the centre: direction (1, 0) by convention
        safe, c, s = 1.0, 1.0, 0.0
    cols[0] = c * c
    cols[1] = 2 * c * s
    cols[2] = s * s
    k = 3
    if tilt:
        cols[3] = c / safe
        cols[4] = s / safe
        k = 5
    if cubic:
        cols[k] = r * c**3
        cols[k + 1] = r * c * c * s
        cols[k + 2] = r * c * s * s
        cols[k + 3] = r * s**3
    return r


@numba.njit(cache=True)
def _denoised_denominator(cols, n_shape, r2, height_beta, i):
    """``D^2 = r^2 + (zhat - z0)^2`` with ``zhat`` the plain height fit ``height_beta[i]`` at the pair."""
    # zhat = [-r^2/2 * cols, 1] . beta, the constant column last (as the numpy path sums it)
    zhat = 0.0
    for a in range(n_shape):
        zhat += -0.5 * r2 * cols[a] * height_beta[i, a]
    z0 = height_beta[i, n_shape]
    zhat += z0
    dz = zhat - z0
    return r2 + dz * dz


@numba.njit(parallel=True, cache=True)
def _assemble_normal_equations(
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
        ``_CHORD``, ``_HEIGHT`` or ``_DENOISED_HEIGHT``.
    height_beta : ndarray, shape (n, p) or (0, p)
        The plain height fit (for ``_DENOISED_HEIGHT`` only).
    G, rhs, yy : ndarray, shape (n, p, p), (n, p), (n,)
        Output: ``X^T W X``, ``X^T W y``, ``y^T W y``.
    G2 : ndarray, shape (n, p, p) or (0, p, p)
        Output if not empty: ``X^T W^2 S^2 X`` with ``S`` the response noise per
        unit height noise (``2 / D^2`` for chord curvatures, 1 for heights).
    """
    n = indptr.shape[0] - 1
    p = rhs.shape[1]
    n_shape = 3 + 2 * tilt + 4 * cubic
    with_g2 = G2.shape[0] > 0
    for i in numba.prange(n):
        cols = np.empty(n_shape)
        X = np.empty(p)
        # full p x p sums, row-major in 1-d: the inner loops run over contiguous memory
        Gi = np.zeros(p * p)
        G2i = np.zeros(p * p)
        ri = np.zeros(p)
        yyi = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            x, y, z = _local_coordinates(points, centres, i, indices[k], e1, e2, normals, unit[i])
            r = _fill_shape_columns(x, y, tilt, cubic, cols)
            r2 = r * r
            if kind == _CHORD:
                D2 = r2 + z * z
                if D2 > 0:
                    response = -2.0 * z / D2
                    # a height error eps moves kN by 2 eps / D^2
                    noise = 2.0 / D2
                else:
                    response = 0.0
                    noise = 0.0
                for a in range(p):
                    X[a] = cols[a]
            else:
                if kind == _HEIGHT:
                    D2 = r2
                else:
                    D2 = _denoised_denominator(cols, n_shape, r2, height_beta, i)
                for a in range(n_shape):
                    X[a] = -0.5 * D2 * cols[a]
                X[n_shape] = 1.0
                response = z
                noise = 1.0
            w = weights[k]
            yyi += w * response * response
            if with_g2:
                s2 = w * w * noise * noise
                for a in range(p):
                    wx = X[a] * w
                    sx = X[a] * s2
                    ri[a] += wx * response
                    row = a * p
                    for b in range(p):
                        Gi[row + b] += wx * X[b]
                        G2i[row + b] += sx * X[b]
            else:
                for a in range(p):
                    wx = X[a] * w
                    ri[a] += wx * response
                    row = a * p
                    for b in range(p):
                        Gi[row + b] += wx * X[b]
        for a in range(p):
            rhs[i, a] = ri[a]
            for b in range(p):
                G[i, a, b] = Gi[a * p + b]
                if with_g2:
                    G2[i, a, b] = G2i[a * p + b]
        yy[i] = yyi


@numba.njit(parallel=True, cache=True)
def _weighted_height_residual(
    points, centres, indptr, indices, weights, unit, normals, e1, e2, tilt, cubic, kind, height_beta, beta, sigma2
):
    """Weighted mean square height residual of each centre's final fit, into ``sigma2``.

    ``kind`` is ``_CHORD`` (a kN residual, times ``D^2 / 2`` to make it a height) or
    ``_DENOISED_HEIGHT`` (``beta`` the refit of ``height_beta``); other
    arguments as :func:`_assemble_normal_equations`. Units of ``unit``.
    """
    n = indptr.shape[0] - 1
    p = beta.shape[1]
    n_shape = 3 + 2 * tilt + 4 * cubic
    for i in numba.prange(n):
        cols = np.empty(n_shape)
        weighted_sq = 0.0
        total_weight = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            x, y, z = _local_coordinates(points, centres, i, indices[k], e1, e2, normals, unit[i])
            r = _fill_shape_columns(x, y, tilt, cubic, cols)
            r2 = r * r
            if kind == _CHORD:
                D2 = r2 + z * z
                kN = -2.0 * z / D2 if D2 > 0 else 0.0
                fitted = 0.0
                for a in range(p):
                    fitted += cols[a] * beta[i, a]
                resid = (kN - fitted) * D2 / 2
            else:
                D2 = _denoised_denominator(cols, n_shape, r2, height_beta, i)
                fitted = 0.0
                for a in range(n_shape):
                    fitted += -0.5 * D2 * cols[a] * beta[i, a]
                fitted += beta[i, n_shape]
                resid = z - fitted
            w = weights[k]
            weighted_sq += w * resid * resid
            total_weight += w
        sigma2[i] = weighted_sq / max(total_weight, 1e-300)


def _fit(kind, p, geometry, height_beta=None, final=False):
    """Assemble one fit with the kernel and solve it.

    A ``final`` fit (the last pass's, whose diagnostics the result reports) is
    solved by :func:`heatcurv.chordfit.solve_normal_equations` exactly as
    ``segment_lstsq`` solves it, with the mean-curvature contrast, and returns
    ``beta, rss, well_posed, variance``. The fits before it only pass their
    coefficients on (the numpy path computes and drops the rest), so they
    skip ``G2`` and the eigenvalues and return ``beta`` alone.
    """
    indptr = geometry[2]
    n = indptr.shape[0] - 1
    G = np.empty((n, p, p))
    rhs = np.empty((n, p))
    yy = np.empty(n)
    G2 = np.empty((n if final else 0, p, p))
    if height_beta is None:
        height_beta = np.empty((0, p))
    _assemble_normal_equations(*geometry, kind, height_beta, G, rhs, yy, G2)
    if not final:
        return ridge_solve(G, rhs)[0]
    return solve_normal_equations(G, rhs, yy, contrast=_mean_contrast(p), G2=G2)


def chord_fit_compiled(
    points: np.ndarray,
    nbhd: Neighbourhood,
    normals: np.ndarray,
    weights: np.ndarray,
    *,
    passes: int = 2,
    tilt: bool = True,
    cubic: bool = True,
    denoise: bool = False,
    centres: np.ndarray | None = None,
) -> ChordFit:
    """:func:`heatcurv.chordfit.chord_fit` with compiled per-pair sums.

    Same parameters and result as :func:`heatcurv.chordfit.chord_fit`; the
    results agree with its numpy path to rounding (the sums run in another order).
    """
    if centres is None:
        centres = points
    points = np.ascontiguousarray(points, dtype=np.float64)
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    indptr = np.ascontiguousarray(nbhd.indptr, dtype=np.int64)
    indices = np.ascontiguousarray(nbhd.indices)  # int32 or int64: one compilation each
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    # the fit works in units of each centre's ball radius, as the numpy path
    unit = np.ascontiguousarray(nbhd.radius, dtype=np.float64)
    tilt, cubic = bool(tilt), bool(cubic)
    n_shape = 3 + 2 * tilt + 4 * cubic
    nrm = np.ascontiguousarray(normals, dtype=np.float64)
    n_passes = max(1, passes)
    for k in range(n_passes):
        final = k == n_passes - 1
        e1, e2 = tangent_frames(nrm)
        geometry = (points, centres, indptr, indices, weights, unit, nrm, e1, e2, tilt, cubic)
        if not denoise:
            fitted = _fit(_CHORD, n_shape, geometry, final=final)
            height_beta = np.empty((0, n_shape))
        else:
            # 1) plain height fit; 2) refit with the chord denominator of its heights
            height_beta = _fit(_HEIGHT, n_shape + 1, geometry)
            fitted = _fit(_DENOISED_HEIGHT, n_shape + 1, geometry, height_beta=height_beta, final=final)
        if final:
            beta, _, ok, var_factor = fitted
            sigma2 = np.empty(nbhd.n_points)
            _weighted_height_residual(*geometry, _DENOISED_HEIGHT if denoise else _CHORD, height_beta, beta, sigma2)
        else:
            beta = fitted
        pc, refined = _principal_and_refined_normal(beta[:, :n_shape], unit, e1, e2, nrm, tilt)
        used, nrm = nrm, refined
    return _chord_fit_result(pc, ok, used, sigma2, var_factor, unit)
