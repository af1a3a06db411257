"""numpy reference of :func:`heatcurv.chordfit.chord_fit` (the former numpy backend).

Builds the per-pair arrays (local coordinates, model columns, responses) and
solves every centre's weighted least squares with
:func:`heatcurv.chordfit.segment_lstsq` (batched products, LU solve, LAPACK
eigenvalues); the compiled fit accumulates the same normal equations pair by
pair and solves them by Cholesky, so the two agree to rounding, amplified by
the normal matrices' condition numbers.
"""

import numpy as np

from heatcurv._kernels.chordfit import (
    LOW_NOISE_LIMIT,
    LOW_NOISE_MIN_LAMBDA,
    LOW_NOISE_SIGMA,
    LOW_NOISE_TRIED,
    MIN_DOF_FRACTION,
    QUARTIC_COLUMNS,
)
from heatcurv.chordfit import (
    ChordFit,
    _chord_fit_result,
    _mean_contrast,
    _model_coefficients,
    _principal_and_refined_normal,
    segment_lstsq,
)
from heatcurv.neighbourhood import Neighbourhood
from heatcurv.normals import tangent_frames

__all__ = ["chord_fit", "residual_variance"]


def _local_coordinates(centres, points, nbhd, normals):
    rows = nbhd.rows
    d = points[nbhd.indices] - centres[rows]
    e1, e2 = tangent_frames(normals)
    x = np.einsum("ij,ij->i", d, e1[rows])
    y = np.einsum("ij,ij->i", d, e2[rows])
    z = np.einsum("ij,ij->i", d, normals[rows])
    return x, y, z, e1, e2


def _shape_columns(x, y, tilt: bool, cubic: bool):
    """Columns of the kN model: tensor (3), tilt (2), cubic (4); shape (nnz, p)."""
    r = np.sqrt(x * x + y * y)
    safe = np.where(r > 0, r, 1.0)
    c, s = np.where(r > 0, x / safe, 1.0), np.where(r > 0, y / safe, 0.0)
    cols = [c * c, 2 * c * s, s * s]
    if tilt:
        cols += [c / safe, s / safe]
    if cubic:
        cols += [r * c**3, r * c * c * s, r * c * s * s, r * s**3]
    return np.stack(cols, 1), r


def residual_variance(nbhd: Neighbourhood, weights: np.ndarray, resid: np.ndarray, p: int) -> np.ndarray:
    """Noise variance from weighted residuals, corrected for the ``p`` degrees of freedom the fit used.

    See ``_unbiased_mean_square`` in :mod:`heatcurv._kernels.chordfit`.
    """
    total = nbhd.segment_sum(weights)
    mean_sq = nbhd.segment_sum(weights * resid * resid) / np.maximum(total, 1e-300)
    n_eff = np.maximum(total * total / np.maximum(nbhd.segment_sum(weights * weights), 1e-300), 1e-300)
    return mean_sq / np.maximum(1.0 - p / n_eff, MIN_DOF_FRACTION)


def chord_fit(
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
    low_noise: bool = False,
) -> ChordFit:
    """:func:`heatcurv.chordfit.chord_fit` in numpy: same parameters, same result to rounding."""
    if centres is None:
        centres = points
    # in units of each centre's ball radius, as the compiled fit
    unit = nbhd.radius
    unit_pair = np.repeat(unit, nbhd.counts)
    nrm = normals
    for number in range(max(1, passes)):
        last = number == max(1, passes) - 1
        x, y, z, e1, e2 = _local_coordinates(centres, points, nbhd, nrm)
        x, y, z = x / unit_pair, y / unit_pair, z / unit_pair
        cols, r = _shape_columns(x, y, tilt, cubic)
        r2 = r * r
        if not denoise:
            D2 = r2 + z * z
            kN = np.where(D2 > 0, -2.0 * z / np.where(D2 > 0, D2, 1.0), 0.0)
            contrast = _mean_contrast(cols.shape[1])
            # a height error eps moves kN by 2 eps / D^2: response noise scale per unit sigma
            beta, rss, ok, var_factor = segment_lstsq(
                nbhd, cols, kN, weights, contrast=contrast, noise_scale=2.0 / np.where(D2 > 0, D2, np.inf)
            )
            # height residual: kN residual times D^2 / 2
            resid = (kN - np.einsum("ij,ij->i", cols, beta[nbhd.rows])) * D2 / 2
            sigma2 = residual_variance(nbhd, weights, resid, cols.shape[1])
        else:
            # 1) plain height fit: z = z0 - r^2/2 * model
            design = np.concatenate([-0.5 * r2[:, None] * cols, np.ones((len(r2), 1))], 1)
            beta, rss, ok = segment_lstsq(nbhd, design, z, weights)
            if not last:  # an earlier pass refines the normal by the height fit's tilt alone
                _, nrm = _principal_and_refined_normal(beta[:, :-1], unit, e1, e2, nrm, tilt)
                continue
            zhat = np.einsum("ij,ij->i", design, beta[nbhd.rows])
            z0 = beta[nbhd.rows, -1]
            jet_sigma2 = residual_variance(nbhd, weights, z - zhat, design.shape[1])
            # 2) refit with the denoised chord denominator r^2 + (zhat - z0)^2
            D2 = r2 + (zhat - z0) ** 2
            design = np.concatenate([-0.5 * D2[:, None] * cols, np.ones((len(r2), 1))], 1)
            contrast = _mean_contrast(design.shape[1])
            beta, rss, ok, var_factor = segment_lstsq(nbhd, design, z, weights, contrast=contrast)
            resid = z - np.einsum("ij,ij->i", design, beta[nbhd.rows])
            sigma2 = residual_variance(nbhd, weights, resid, design.shape[1])
            beta = beta[:, :-1]
            if not low_noise:
                continue_low = False
            else:
                low, low_fit = _low_noise_refit(nbhd, x, y, z, r2, cols, weights, jet_sigma2)
                continue_low = bool(low.any())
            quartic = np.zeros((len(beta), QUARTIC_COLUMNS))
            if continue_low:
                lbeta, lok, lvar = low_fit
                n_shape = cols.shape[1]
                beta[low], ok[low], var_factor[low] = lbeta[low, :n_shape], lok[low], lvar[low]
                quartic[low] = lbeta[low, n_shape:-1]
                sigma2[low] = jet_sigma2[low]
        pc, refined = _principal_and_refined_normal(beta, unit, e1, e2, nrm, tilt)
        used, nrm = nrm, refined
    coefficients = _model_coefficients(beta, tilt, cubic)
    if denoise and low_noise:  # the low-noise refit carries its quartic terms (zeros where it is not used)
        coefficients = np.concatenate([coefficients, quartic], 1)
    return _chord_fit_result(pc, ok, used, sigma2, var_factor, unit, coefficients)


def _low_noise_refit(nbhd, x, y, z, r2, cols, weights, jet_sigma2):
    """The low-noise refit of :func:`heatcurv.chordfit._denoised_refit` at every centre, and where it is used.

    Returns ``low`` (bool per centre) and ``(beta, well_posed, variance)`` of the refit
    (``beta``: shape columns, quartic columns, offset).
    """
    rows = nbhd.rows
    limit2 = (LOW_NOISE_LIMIT * LOW_NOISE_SIGMA) ** 2
    tried = jet_sigma2 < LOW_NOISE_TRIED**2 * limit2
    if not tried.any():
        return tried, None
    safe = np.where(r2 > 0, r2, 1.0)
    quartic = np.stack([x**4, x**3 * y, x * x * y * y, x * y**3, y**4], 1) / safe[:, None]
    shape = np.concatenate([cols, quartic], 1)
    # the height fit with quartic terms: its residual and heights
    design = np.concatenate([-0.5 * r2[:, None] * shape, np.ones((len(r2), 1))], 1)
    qbeta = segment_lstsq(nbhd, design, z, weights, jacobi=True)[0]
    own = residual_variance(nbhd, weights, z - np.einsum("ij,ij->i", design, qbeta[rows]), design.shape[1])
    low = tried & (own < limit2)
    # the refit: D^2 from the quartic heights, pairs weighted w lambda^4 / (D^4 + lambda^4)
    dz = np.einsum("ij,ij->i", design[:, :-1], qbeta[rows, :-1])
    D2 = r2 + dz * dz
    lam4 = np.maximum(own / LOW_NOISE_SIGMA**2, LOW_NOISE_MIN_LAMBDA**4)[rows]
    design = np.concatenate([-0.5 * D2[:, None] * shape, np.ones((len(r2), 1))], 1)
    beta, _, ok, var_factor = segment_lstsq(
        nbhd, design, z, weights * lam4 / (D2 * D2 + lam4), contrast=_mean_contrast(design.shape[1]), jacobi=True
    )
    return low, (beta, ok, var_factor)
