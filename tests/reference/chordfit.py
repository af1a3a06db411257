"""An independent numpy reimplementation of :func:`heatcurv.fits.chordfit.chord_fit`, from the maths.

It shares no code with the fit it checks: the tangent frames, the model
columns, the responses, the least squares, the principal curvatures and
directions, the tilt-corrected normal, the residual sigma and the variance of
the mean are all written here again, from the model the docstrings of
:mod:`heatcurv.fits.chordfit` and :mod:`heatcurv._kernels.chordfit` state (and the
paper's eq 2.12, the chord curvature ``kN_ij = 2 (xi - xj) . n / |xi - xj|^2``).
Only containers come from heatcurv (:class:`~heatcurv.fits.chordfit.ChordFit`,
:class:`~heatcurv.fits.principal.PrincipalCurvatures`; the
:class:`~heatcurv.geometry.neighbourhood.Neighbourhood` argument is read as plain CSR
arrays), and the documented parameters of the method: ``MIN_DOF_FRACTION``
(floor of the residual's degrees-of-freedom correction), ``WELL_POSED_RCOND``
(the well-posedness threshold) and the low-noise refit's ``LOW_NOISE_MIN_LAMBDA`` from
:mod:`heatcurv._kernels.chordfit`, and the refit's ``low_noise_sigma``, ``low_noise_limit`` and
``low_noise_tried`` from :data:`heatcurv.tuning.TUNING`. The Tikhonov ridge, 1e-10 of ``trace(G) / p``
(of each diagonal entry for the quartic fits), is the documented default of
:func:`reference.lstsq.segment_lstsq`'s ``ridge`` and is written here as
:data:`RIDGE`.

Where the compiled fit accumulates normal equations ``X^T W X`` pair by pair and
solves them by Cholesky, this reference never forms them: it solves each centre's
weighted least squares by the singular value decomposition of ``W^(1/2) X`` (by
way of a Householder QR; the ridge as Tikhonov filter factors
``s / (s^2 + ridge)``), judges well-posedness by those singular values, and takes
the variance of the mean curvature as the sum over the pairs of the squared
sensitivities of ``c . beta`` to each response, its definition. The two agree to
rounding amplified by the condition numbers (the compiled solve's error grows as
``kappa(G) eps``, this one's about as its square root, for small residuals).

Conventions the compiled fit documents and this reference follows: a neighbour
straight above its centre (``r = 0``) has direction ``(1, 0)`` and is treated as
``r = 1`` in the tensor and tilt columns, 0 in the cubic and quartic ones; a pair
at zero distance has chord curvature 0 and no response noise.
"""

import numpy as np

from heatcurv._kernels.chordfit import (
    LOW_NOISE_MIN_LAMBDA,
    MIN_DOF_FRACTION,
    WELL_POSED_RCOND,
)
from heatcurv.fits.chordfit import ChordFit
from heatcurv.fits.principal import PrincipalCurvatures
from heatcurv.tuning import TUNING

__all__ = ["chord_fit", "refine_normals", "tangent_frames", "RIDGE"]

#: Tikhonov ridge relative to ``trace(G) / p`` (or to each diagonal entry of ``G``, for the quartic fits).
RIDGE = 1e-10

#: Entries (centres x padded pairs x columns) of one batch of weighted designs.
_BATCH_ENTRIES = 4_000_000


def tangent_frames(normals):
    """``(e1, e2)``, orthonormal, ``e1 x e2 = n``: ``e1`` along ``axis x n`` with the axis least aligned with ``n``.

    The construction :func:`heatcurv.orient.normals.tangent_frames` documents, written
    again (the fit's coefficients are given in this frame).
    """
    n = np.asarray(normals, dtype=float)
    axis = np.eye(3)[np.argmin(np.abs(n), axis=1)]
    e1 = np.cross(axis, n)
    e1 = e1 / np.sqrt(np.sum(e1 * e1, axis=1))[:, None]
    return e1, np.cross(n, e1)


def _pair_rows(indptr):
    return np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))


def _per_row_sum(indptr, values):
    """Per-row sums of per-pair values, 0 for empty rows."""
    return np.bincount(_pair_rows(indptr), weights=values, minlength=len(indptr) - 1)


def _local_coordinates(points, centres, indptr, indices, normals, e1, e2, unit):
    """``(x, y, z)`` of every pair in its centre's frame ``(e1, e2, n)``, and ``|xj - xi|^2``, units of the radius."""
    rows = _pair_rows(indptr)
    d = (points[indices] - centres[rows]) / unit[rows, None]
    x = np.sum(d * e1[rows], axis=1)
    y = np.sum(d * e2[rows], axis=1)
    z = np.sum(d * normals[rows], axis=1)
    return x, y, z, np.sum(d * d, axis=1)


def _directions(x, y):
    """``r``, ``cos``, ``sin`` of every pair's tangential offset (``r = 0``: direction (1, 0))."""
    r = np.hypot(x, y)
    flat = r == 0
    safe = np.where(flat, 1.0, r)
    return r, np.where(flat, 1.0, x / safe), np.where(flat, 0.0, y / safe)


def _shape_columns(x, y, tilt, cubic):
    """Columns of the kN model, shape (nnz, 3 + 2 tilt + 4 cubic).

    ``kN = a c^2 + 2 b c s + d s^2 + (t1 c + t2 s) / r + r (g0 c^3 + g1 c^2 s + g2 c s^2 + g3 s^3)``.
    """
    r, c, s = _directions(x, y)
    columns = [c * c, 2 * c * s, s * s]
    if tilt:
        inv_r = 1.0 / np.where(r == 0, 1.0, r)
        columns += [c * inv_r, s * inv_r]
    if cubic:
        columns += [r * c**3, r * c * c * s, r * c * s * s, r * s**3]
    return np.stack(columns, axis=1)


def _quartic_columns(x, y):
    """``r^2 c^4, r^2 c^3 s, r^2 c^2 s^2, r^2 c s^3, r^2 s^4`` (0 at ``r = 0``), shape (nnz, 5)."""
    r, c, s = _directions(x, y)
    r2 = r * r
    return np.stack([r2 * c**4, r2 * c**3 * s, r2 * c * c * s * s, r2 * c * s**3, r2 * s**4], axis=1)


def _weighted_lstsq(indptr, design, response, weights, jacobi=False, contrast=None, noise=None):
    """Each row's ridge-regularised weighted least squares, by the SVD of ``W^(1/2) X``.

    Minimises ``|W^(1/2) (y - X beta)|^2 + RIDGE beta^T D beta`` with ``D = trace(X^T W X) / p I``
    (``jacobi``: ``diag(X^T W X)``, ``trace / p`` where an entry is 0), per row. The SVD is that of
    the triangular factor ``R`` of a Householder QR of ``[W^(1/2) X, W^(1/2) y]`` (``W^(1/2) X = Q R``,
    whose last column gives ``Q^T W^(1/2) y``): the singular values of ``R`` are those of ``W^(1/2) X``.

    Returns
    -------
    beta : ndarray, shape (n, p)
    well_posed : ndarray, shape (n,), bool
        Only with ``contrast``: ``s_min^2 > WELL_POSED_RCOND s_max^2`` of ``W^(1/2) X`` (the
        eigenvalues of ``X^T W X``).
    variance : ndarray, shape (n, c, c)
        Only with ``contrast``, rows ``c_k`` of shape (c, p): ``Cov(c_k . beta, c_l . beta)`` per unit
        noise variance when the response of pair ``j`` has noise ``noise_j`` (default 1) times the
        unit, ``sum_j (dc_k.beta / dy_j) (dc_l.beta / dy_j) noise_j^2``; NaN for a centre without
        weighted pairs (no fit: its covariance is undefined).
    """
    n, p = len(indptr) - 1, design.shape[1]
    counts = np.diff(indptr)
    beta = np.zeros((n, p))
    well_posed = np.zeros(n, dtype=bool)
    n_contrasts = 0 if contrast is None else np.atleast_2d(contrast).shape[0]
    variance = np.zeros((n, n_contrasts, n_contrasts))
    root_w = np.sqrt(weights)
    # batches of centres with similar numbers of pairs, each padded with zero rows to its longest
    # (and to at least p + 1 rows: R is then (p + 1) x (p + 1))
    order = np.argsort(counts, kind="stable")
    lo = 0
    while lo < n:
        hi = lo + 1
        while hi < n and (hi - lo + 1) * max(int(counts[order[hi]]), p + 1) * p <= _BATCH_ENTRIES:
            hi += 1
        width = max(int(counts[order[hi - 1]]), p + 1)
        batch = order[lo:hi]
        local = np.repeat(np.arange(hi - lo), counts[batch])
        slot = np.arange(local.size) - np.repeat(np.cumsum(counts[batch]) - counts[batch], counts[batch])
        pairs = indptr[batch][local] + slot
        A = np.zeros((hi - lo, width, p))
        y = np.zeros((hi - lo, width))
        A[local, slot] = root_w[pairs, None] * design[pairs]
        y[local, slot] = root_w[pairs] * response[pairs]
        # the ridge's scale: trace / p, or each column's squared norm (the diagonal of X^T W X)
        column_sq = np.sum(A * A, axis=1)
        mean_sq = np.maximum(column_sq.sum(axis=1) / p, 1e-300)
        if jacobi:
            scale = np.sqrt(np.where(column_sq > 0, column_sq, mean_sq[:, None]))
        else:
            scale = np.repeat(np.sqrt(mean_sq)[:, None], p, axis=1)
        # in the scaled unknowns u = scale * beta the ridge is RIDGE |u|^2: Tikhonov filter factors
        R = np.linalg.qr(np.concatenate([A / scale[:, None, :], y[:, :, None]], axis=2), mode="r")
        U, s, Vt = np.linalg.svd(R[:, :p, :p])
        Uty = np.einsum("mqk,mq->mk", U, R[:, :p, p])
        u = np.einsum("mkp,mk->mp", Vt, s / (s * s + RIDGE) * Uty)
        beta[batch] = u / scale
        if contrast is not None:
            plain = np.linalg.svd(R[:, :p, :p] * scale[:, None, :], compute_uv=False)  # W^(1/2) X = Q R diag(scale)
            well_posed[batch] = plain[:, -1] ** 2 > WELL_POSED_RCOND * np.maximum(plain[:, 0] ** 2, 1e-300)
            # dc.beta / dy_j = w_j X_j . g, g = (X^T W X + ridge)^-1 c (the regularised normal matrix)
            with np.errstate(over="ignore", invalid="ignore"):  # (a centre without pairs: NaN below)
                cs = np.atleast_2d(np.asarray(contrast, dtype=float))[None, :, :] / scale[:, None, :]
                inner = np.einsum("mkp,mcp->mck", Vt, cs) / (s * s + RIDGE)[:, None, :]
                g = np.einsum("mkp,mck->mcp", Vt, inner) / scale[:, None, :]
            sensitivity = weights[pairs, None] * np.einsum("jp,jcp->jc", design[pairs], g[local])
            if noise is not None:
                sensitivity = sensitivity * noise[pairs, None]
            block = np.zeros((hi - lo, n_contrasts, n_contrasts))
            np.add.at(block, local, sensitivity[:, :, None] * sensitivity[:, None, :])
            variance[batch] = block
        lo = hi
    if contrast is None:
        return beta
    variance[np.bincount(_pair_rows(indptr), weights=weights, minlength=n) == 0] = np.nan
    return beta, well_posed, variance


def _residual_variance(indptr, weights, residual, p):
    """Noise variance from weighted residuals: ``mean_w(r^2) / max(1 - p / n_eff, MIN_DOF_FRACTION)``.

    ``n_eff = (sum w)^2 / sum w^2`` (0 without neighbours, where the mean square is 0 too).
    """
    total = _per_row_sum(indptr, weights)
    total_sq = _per_row_sum(indptr, weights * weights)
    weighted_sq = _per_row_sum(indptr, weights * residual * residual)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean_sq = np.where(total > 0, weighted_sq / total, 0.0)
        n_eff = np.where(total_sq > 0, total * total / total_sq, 0.0)
        dof = np.where(n_eff > 0, 1.0 - p / n_eff, -np.inf)
    return mean_sq / np.maximum(dof, MIN_DOF_FRACTION)


def _principal(beta, unit, e1, e2, normals):
    """Eigen-decomposition of the shape operator ``[[a, b], [b, d]] / unit`` written in ``(e1, e2)``."""
    B = np.empty((len(unit), 2, 2))
    B[:, 0, 0] = beta[:, 0] / unit
    B[:, 0, 1] = B[:, 1, 0] = beta[:, 1] / unit
    B[:, 1, 1] = beta[:, 2] / unit
    values, vectors = np.linalg.eigh(B)  # ascending
    k1, k2 = values[:, 1], values[:, 0]
    d1 = vectors[:, 0, 1, None] * e1 + vectors[:, 1, 1, None] * e2
    d2 = np.cross(normals, d1)
    mean = 0.5 * (B[:, 0, 0] + B[:, 1, 1])
    gaussian = B[:, 0, 0] * B[:, 1, 1] - B[:, 0, 1] ** 2
    return k1, k2, d1, d2, mean, gaussian


def _tilted_normal(beta, e1, e2, normals):
    """The normal of the tangent plane the tilt terms measure.

    A tangent plane ``z = g1 x + g2 y`` adds ``-2 z / r^2 = -2 (g1 c + g2 s) / r`` to ``kN``
    (and ``t / r`` columns to a height fit's ``-r^2 / 2`` model likewise), so ``g = -t / 2``;
    that plane's unit normal is ``(-g1, -g2, 1) / |.|`` in the frame ``(e1, e2, n)``.
    """
    g1, g2 = -0.5 * beta[:, 3], -0.5 * beta[:, 4]
    normal = -g1[:, None] * e1 - g2[:, None] * e2 + normals
    return normal / np.linalg.norm(normal, axis=1)[:, None]


def chord_fit(
    points,
    nbhd,
    normals,
    weights,
    *,
    passes=2,
    tilt=True,
    cubic=True,
    denoise=False,
    centres=None,
    low_noise=False,
):
    """:func:`heatcurv.fits.chordfit.chord_fit` from its definition: same parameters, same result to rounding."""
    points = np.asarray(points, dtype=float)
    centres = points if centres is None else np.asarray(centres, dtype=float)
    indptr = np.asarray(nbhd.indptr, dtype=np.int64)
    indices = np.asarray(nbhd.indices, dtype=np.int64)
    weights = np.asarray(weights, dtype=float)
    unit = np.asarray(nbhd.radius, dtype=float)  # the fit's length unit: each centre's ball radius
    n = len(unit)
    n_shape = 3 + 2 * bool(tilt) + 4 * bool(cubic)
    # a, b, d and (tilt) t_1, t_2: their covariance under noise
    contrasts = np.eye(5 if tilt else 3, n_shape + 6)
    normal = np.asarray(normals, dtype=float)
    for number in range(max(1, passes)):
        final = number == max(1, passes) - 1
        e1, e2 = tangent_frames(normal)
        x, y, z, dist2 = _local_coordinates(points, centres, indptr, indices, normal, e1, e2, unit)
        cols = _shape_columns(x, y, tilt, cubic)
        r2 = x * x + y * y
        ones = np.ones((len(z), 1))
        quartic = np.zeros((n, 5))
        if not denoise:
            # eq 2.12 with xi - xj = -(x, y, z): kN = -2 z / |xj - xi|^2; a height error e moves it by 2 e / D^2
            moving = dist2 > 0
            inv = 1.0 / np.where(moving, dist2, 1.0)
            kN = np.where(moving, -2.0 * z * inv, 0.0)
            sensitivity = np.where(moving, 2.0 * inv, 0.0)
            if not final:
                beta = _weighted_lstsq(indptr, cols, kN, weights)
                normal = _tilted_normal(beta, e1, e2, normal) if tilt else normal
                continue
            beta, ok, var = _weighted_lstsq(
                indptr, cols, kN, weights, contrast=contrasts[:, :n_shape], noise=sensitivity
            )
            # the kN residual as a height: times D^2 / 2
            residual = (kN - np.sum(cols * beta[_pair_rows(indptr)], axis=1)) * dist2 / 2
            sigma2 = _residual_variance(indptr, weights, residual, n_shape)
        else:
            rows = _pair_rows(indptr)
            # the height fit (jet): z = z0 - r^2 / 2 * model
            jet_design = np.hstack([-0.5 * r2[:, None] * cols, ones])
            jet = _weighted_lstsq(indptr, jet_design, z, weights)
            if not final:  # the height fit's tilt alone corrects the normal of an earlier pass
                normal = _tilted_normal(jet, e1, e2, normal) if tilt else normal
                continue
            jet_sigma2 = _residual_variance(indptr, weights, z - np.sum(jet_design * jet[rows], axis=1), n_shape + 1)
            # the refit with the denoised chord denominator D^2 = r^2 + (zhat - z0)^2
            dz = -0.5 * r2 * np.sum(cols * jet[rows, :n_shape], axis=1)
            D2 = r2 + dz * dz
            design = np.hstack([-0.5 * D2[:, None] * cols, ones])
            beta, ok, var = _weighted_lstsq(indptr, design, z, weights, contrast=contrasts[:, : n_shape + 1])
            sigma2 = _residual_variance(indptr, weights, z - np.sum(design * beta[rows], axis=1), n_shape + 1)
            noise2 = sigma2.copy()
            if low_noise:
                low, low_fit, low_noise2 = _low_noise_refit(indptr, weights, cols, _quartic_columns(x, y), r2, z,
                                                            jet_sigma2, len(contrasts))
                low_beta, low_ok, low_var = low_fit
                beta[low, :n_shape], beta[low, n_shape] = low_beta[low, :n_shape], low_beta[low, -1]
                quartic[low] = low_beta[low, n_shape:-1]
                ok[low], var[low], sigma2[low] = low_ok[low], low_var[low], jet_sigma2[low]
                noise2[low] = low_noise2[low]
        k1, k2, d1, d2, mean, gaussian = _principal(beta, unit, e1, e2, normal)
    coefficients = np.zeros((n, 9))
    coefficients[:, :3] = beta[:, :3]
    if tilt:
        coefficients[:, 3:5] = beta[:, 3:5]
    if cubic:
        coefficients[:, 5:9] = beta[:, 3 + 2 * bool(tilt) : n_shape]
    if denoise and low_noise:
        coefficients = np.hstack([coefficients, quartic])
    principal = PrincipalCurvatures(k1=k1, k2=k2, d1=d1, d2=d2, mean=mean, gaussian=gaussian, well_posed=ok)
    # back to the cloud's units: sigma scales with the radius
    noise = np.sqrt(sigma2 if not denoise else noise2) * unit
    return ChordFit(principal=principal, normals=normal, sigma=np.sqrt(sigma2) * unit, noise=noise,
                    noise_factors=_noise_factors(var, beta, unit), coefficients=coefficients)


def _noise_factors(cov, beta, unit):
    """Noise variances of mean, k1, k2, K and the normal's angle per unit height-noise variance, shape (n, 5).

    The delta method on the shape operator ``B = [[a, b], [b, d]]``: each field ``f(a, b, d)``
    has variance ``grad f^T Cov grad f``, with the gradients of the mean ``(1/2, 0, 1/2)``, of an
    eigenvalue ``(v_x^2, 2 v_x v_y, v_y^2)`` (``v`` its unit eigenvector) and of ``a d - b^2``;
    the normal turns by the tilt ``g = -t / 2``. Coefficients are in units of the ball radius
    ``unit``: a height noise ``e`` is ``e / unit`` there and a curvature ``a / unit``.
    """
    n = len(unit)
    B = np.empty((n, 2, 2))
    B[:, 0, 0], B[:, 0, 1], B[:, 1, 0], B[:, 1, 1] = beta[:, 0], beta[:, 1], beta[:, 1], beta[:, 2]
    _, vectors = np.linalg.eigh(B)
    grads = [np.tile([0.5, 0.0, 0.5], (n, 1))]
    for column in (1, 0):  # k1: the larger eigenvalue
        v = vectors[:, :, column]
        grads.append(np.stack([v[:, 0] ** 2, 2 * v[:, 0] * v[:, 1], v[:, 1] ** 2], axis=1))
    grads.append(np.stack([beta[:, 2], -2 * beta[:, 1], beta[:, 0]], axis=1) / unit[:, None])
    out = np.zeros((n, 5))
    for column, g in enumerate(grads):
        out[:, column] = np.einsum("ni,nij,nj->n", g, cov[:, :3, :3], g) / unit**4
    if cov.shape[1] == 5:
        out[:, 4] = (cov[:, 3, 3] + cov[:, 4, 4]) / 4 / unit**2
    return out


def refine_normals(points, nbhd, normals, weights, *, tilt=True, cubic=True, denoise=False, centres=None):
    """:func:`heatcurv.fits.chordfit.refine_normals`: one fit's tilt-corrected normals (the first of two passes).

    The chord fit's tilt, or with ``denoise`` the plain height fit's; the normals unchanged without ``tilt``.
    """
    normal = np.asarray(normals, dtype=float)
    if not tilt:
        return normal
    points = np.asarray(points, dtype=float)
    centres = points if centres is None else np.asarray(centres, dtype=float)
    indptr, indices = np.asarray(nbhd.indptr, dtype=np.int64), np.asarray(nbhd.indices, dtype=np.int64)
    weights, unit = np.asarray(weights, dtype=float), np.asarray(nbhd.radius, dtype=float)
    e1, e2 = tangent_frames(normal)
    x, y, z, dist2 = _local_coordinates(points, centres, indptr, indices, normal, e1, e2, unit)
    cols = _shape_columns(x, y, tilt, cubic)
    if denoise:
        design = np.hstack([-0.5 * (x * x + y * y)[:, None] * cols, np.ones((len(z), 1))])
        beta = _weighted_lstsq(indptr, design, z, weights)
    else:
        moving = dist2 > 0
        beta = _weighted_lstsq(indptr, cols, np.where(moving, -2.0 * z / np.where(moving, dist2, 1.0), 0.0), weights)
    return _tilted_normal(beta, e1, e2, normal)


def _low_noise_refit(indptr, weights, cols, quartic, r2, z, jet_sigma2, n_contrasts):
    """The low-noise refit of the denoised form, where it is used.

    Tried where the height fit's residual is below ``tried limit sigma0`` and kept where the residual of the height
    fit with quartic terms is below ``limit sigma0`` (``TUNING.low_noise_tried``, ``.low_noise_limit``,
    ``.low_noise_sigma``).
    The refit: heights against ``[-D^2 / 2 (columns, quartic), 1]``, ``D^2 = r^2 + (zhat - z0)^2`` from the
    quartic height fit, pairs weighted ``w lambda^4 / (D^4 + lambda^4)``, ``lambda^4 = (sigma / sigma0)^2``
    (at least ``LOW_NOISE_MIN_LAMBDA^4``); both fits with the ridge relative to each diagonal entry.

    Returns ``low`` (bool per centre), ``(beta, well_posed, variance)`` of the refit, ``beta``
    the shape columns, the quartic ones and the offset, and the quartic height fit's residual
    variance (the noise at a low-noise centre).
    """
    rows = _pair_rows(indptr)
    ones = np.ones((len(z), 1))
    shape = np.hstack([cols, quartic])
    limit2 = (TUNING.low_noise_limit * TUNING.low_noise_sigma) ** 2
    height_design = np.hstack([-0.5 * r2[:, None] * shape, ones])
    height = _weighted_lstsq(indptr, height_design, z, weights, jacobi=True)
    own = _residual_variance(indptr, weights, z - np.sum(height_design * height[rows], axis=1), shape.shape[1] + 1)
    low = (jet_sigma2 < TUNING.low_noise_tried**2 * limit2) & (own < limit2)
    dz = -0.5 * r2 * np.sum(shape * height[rows, :-1], axis=1)
    D2 = r2 + dz * dz
    lam4 = np.maximum(own / TUNING.low_noise_sigma**2, LOW_NOISE_MIN_LAMBDA**4)[rows]
    contrast = np.eye(n_contrasts, shape.shape[1] + 1)  # a, b, d (and t_1, t_2)
    fit = _weighted_lstsq(
        indptr, np.hstack([-0.5 * D2[:, None] * shape, ones]), z, weights * lam4 / (D2 * D2 + lam4),
        jacobi=True, contrast=contrast,
    )
    return low, fit, own
