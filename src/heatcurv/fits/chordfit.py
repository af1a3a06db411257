"""The default estimator's curvature fit: edge chord curvatures with tilt and cubic terms.

The paper's principal fit (section 3, :mod:`heatcurv.fits.principal`) fits
Euler's formula ``kN(theta) = k1 cos^2 + k2 sin^2`` to the edge normal
curvatures ``kN_ij = 2 (xi-xj).n / |xi-xj|^2`` (eq 2.12). ``kN_ij`` is the
curvature of the circle through ``x_i`` and ``x_j`` tangent to the plane
normal to ``n``: exact on any circle, which makes it far better than a
height-function (jet) fit of the same order. Two things spoil it on real
clouds, and this module adds a term for each:

* the normal is only estimated. A tilt ``g`` of the tangent plane adds
  ``-2 (g . t) / r`` to ``kN`` along the unit tangent direction ``t`` of an
  edge of tangential length ``r``: two odd terms ``cos(theta)/r`` and
  ``sin(theta)/r`` absorb it, and their coefficients correct the normal,
  ``n <- n - g_1 e_1 - g_2 e_2`` (a second pass then refits with the
  corrected normal);
* neighbourhoods are wide enough to see the third-order shape. A cubic
  height ``-C(x, y)/6`` adds ``r C(cos, sin)/3`` to ``kN``: four terms
  ``r cos^3, r cos^2 sin, r cos sin^2, r sin^3``.

The model per point, in its tangent frame ``(e_1, e_2, n)``, is therefore

    kN_ij = a c^2 + 2 b c s + d s^2 + (t_1 c + t_2 s)/r + r (g_0 c^3 + g_1 c^2 s + g_2 c s^2 + g_3 s^3)

with ``c, s = cos, sin`` of the edge's tangent direction, fitted by weighted
least squares; ``B = [[a, b], [b, d]]`` gives ``k1, k2, d1, d2`` as in the
paper (section 3), without the constraint of eq 3.1.

Under noise the chord denominator ``|xi - xj|^2 = r^2 + z^2`` is inflated by
the noise in ``z``. The ``denoised`` form fits heights instead of curvatures:
first a plain height fit (``-2 z = r^2 * model``, the classical jet), then a
refit in which the denominator uses the *fitted* heights,
``-2 (z - z_0) = (r^2 + zhat^2) * model``, with an offset ``z_0`` for the
noise of the centre point itself.

Under very low noise (coordinate rounding: about 1e-5 to 1e-4 of the diagonal)
that refit's own bias, the third-order model's, exceeds the noise's error. There
(``low_noise``: the anchors' fits of a cloud in that band, :mod:`heatcurv.fits.anchors`;
never the kernel choice's fits, so its noise gate and Lepski's rule are those of
every other cloud) the denoised form refits with quartic terms ``r^2 c^4 .. r^2 s^4``, the
denominator from a height fit with quartic terms, and pair weights
``w lambda^4 / (D^4 + lambda^4)`` (``lambda^2 = sigma / 6e-4``, ball radii): pairs
nearer than ``lambda`` weigh as in the chord fit (exact on circles), farther ones
as in the height fit (:func:`_denoised_refit`): at a wide kernel its error at the
centres is a fraction of the plain denoised fit's (docs/how_it_works.md, thresholds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._kernels import chordfit as kernels
from ..geometry.neighbourhood import Neighbourhood
from ..orient.normals import tangent_frames
from ..tuning import TUNING
from .principal import PrincipalCurvatures, tensor_to_principal

__all__ = ["NOISE_FIELDS", "ChordFit", "chord_fit", "noise_factors", "refine_normals"]

@dataclass(frozen=True)
class ChordFit:
    """Result of :func:`chord_fit`.

    Attributes
    ----------
    principal : PrincipalCurvatures
        ``k1, k2, d1, d2, mean, gaussian`` and ``well_posed``.
    normals : ndarray, shape (n, 3)
        The normals of the last pass (the starting normals corrected by the
        tilt of every earlier pass); ``d1 x d2 = normals``.
    sigma : ndarray, shape (n,)
        Root-mean-square height residual of the fit (weighted), length units:
        near zero on clean data, the noise level on noisy data.
    noise : ndarray, shape (n,)
        The height noise's standard deviation as the fit estimates it, length
        units: ``sigma``, except at a centre of the low-noise refit, where the
        residual of the height fit with quartic terms (``sigma`` there is the
        plain height fit's, which holds the quartic shape the refit models).
    noise_factors : ndarray, shape (n, 5)
        Variances of the fitted ``mean``, ``k1``, ``k2``, ``gaussian`` and of the
        normal's angle (radians) per unit height-noise variance, columns in the order of
        :data:`NOISE_FIELDS`: ``Var(kappa_M) = sigma^2 * noise_factors[:, 0]`` for
        independent height noise of standard deviation ``sigma`` (the sandwich
        covariance of the weighted fit, :func:`noise_factors`).
    coefficients : ndarray, shape (n, 9) or, for the low-noise refit, (n, 14)
        The last pass's model in the frame ``tangent_frames(normals)``, in units of
        each centre's ball radius: tensor ``a, b, d``, tilt ``t_1, t_2``, cubic
        ``g_0 .. g_3`` and (low-noise refit) quartic ``q_0 .. q_4`` (zeros for terms not
        fitted); :mod:`heatcurv.fits.anchors` evaluates it away from the centre.
    """

    principal: PrincipalCurvatures
    normals: np.ndarray
    sigma: np.ndarray
    noise: np.ndarray
    noise_factors: np.ndarray
    coefficients: np.ndarray | None = None

    @property
    def mean_variance_factor(self) -> np.ndarray:
        """``Var(kappa_M) / sigma^2``, shape (n,): the first column of :attr:`noise_factors`."""
        return self.noise_factors[:, 0]

    def take(self, rows: np.ndarray) -> ChordFit:
        """The fit at the centres ``rows`` (indices, or a mask), in their order."""
        pc = self.principal
        fields = PrincipalCurvatures.__dataclass_fields__
        return ChordFit(
            principal=PrincipalCurvatures(**{name: getattr(pc, name)[rows] for name in fields}),
            normals=self.normals[rows], sigma=self.sigma[rows], noise=self.noise[rows],
            noise_factors=self.noise_factors[rows],
            coefficients=None if self.coefficients is None else self.coefficients[rows],
        )

    @staticmethod
    def concatenate(parts: list) -> ChordFit:
        """Join the fits of consecutive blocks of centres into one.

        Blocks fitted with and without the low-noise refit's quartic terms (anchors of
        several kernel widths, only the wider ones refitted) have 9 and 14 coefficients:
        the 9-column blocks get zeros for the quartic terms they did not fit.
        """
        if len(parts) == 1:
            return parts[0]
        cat = lambda get: np.concatenate([get(p) for p in parts])  # noqa: E731
        fields = PrincipalCurvatures.__dataclass_fields__
        pc = PrincipalCurvatures(**{name: cat(lambda p, name=name: getattr(p.principal, name)) for name in fields})
        coefficients = None
        if all(p.coefficients is not None for p in parts):
            width = max(p.coefficients.shape[1] for p in parts)
            coefficients = cat(lambda p: np.pad(p.coefficients, ((0, 0), (0, width - p.coefficients.shape[1]))))
        return ChordFit(
            principal=pc,
            normals=cat(lambda p: p.normals),
            sigma=cat(lambda p: p.sigma),
            noise=cat(lambda p: p.noise),
            noise_factors=cat(lambda p: p.noise_factors),
            coefficients=coefficients,
        )


#: The fields whose noise variance :attr:`ChordFit.noise_factors` holds, in its column order.
NOISE_FIELDS = ("mean", "k1", "k2", "gaussian", "normal")


def _noise_contrasts(p: int, tilt: bool) -> np.ndarray:
    """Unit contrasts picking ``a, b, d`` and (``tilt``) ``t_1, t_2`` of ``p`` coefficients, shape (3 or 5, p)."""
    return np.eye(5 if tilt else 3, p)


def noise_factors(covariance: np.ndarray, tensor: np.ndarray, d1: np.ndarray, d2: np.ndarray, e1: np.ndarray,
                  e2: np.ndarray, unit: np.ndarray) -> np.ndarray:
    """Noise variances of the mean, principal and Gaussian curvatures and of the normal, shape (n, 5).

    First-order propagation of the coefficients' covariance (the sandwich
    ``G^-1 G2 G^-1`` of the weighted fit): an eigenvalue of ``B = [[a, b], [b, d]]``
    with unit eigenvector ``(c, s)`` in the frame moves by ``c^2 da + 2 c s db + s^2 dd``,
    ``K = a d - b^2`` by ``d da - 2 b db + a dd``, and the normal turns by the tangent
    plane's tilt ``g = -t / 2`` (:func:`_refined_normal`), whose squared angle has
    expectation ``Var(g_1) + Var(g_2)``.

    Parameters
    ----------
    covariance : ndarray, shape (n, 3, 3) or (n, 5, 5)
        ``Cov(a, b, d[, t_1, t_2])`` per unit noise variance, in the fit's units (each
        centre's ball radius; :func:`heatcurv._kernels.chordfit.solve_compiled`).
    tensor : ndarray, shape (n, 3)
        The fitted ``a, b, d``, cloud units (1 / length).
    d1, d2 : ndarray, shape (n, 3)
        The fitted principal directions.
    e1, e2 : ndarray, shape (n, 3)
        The frame of the fit.
    unit : ndarray, shape (n,)
        Each centre's ball radius.

    Returns
    -------
    ndarray, shape (n, 5)
        Columns :data:`NOISE_FIELDS`, per unit height-noise variance in cloud units
        (curvatures ``1 / length^4``, Gaussian ``1 / length^6``, normal ``1 / length^2``,
        its angle in radians); the normal's column is 0 without tilt terms.
    """
    block = covariance[:, :3, :3]

    def along(g):  # g^T Cov g, gradients g of shape (n, 3)
        return np.einsum("ni,nij,nj->n", g, block, g)

    n = covariance.shape[0]
    out = np.zeros((n, 5))
    out[:, 0] = along(np.broadcast_to([0.5, 0.0, 0.5], (n, 3)))
    for column, direction in ((1, d1), (2, d2)):
        c, s = np.einsum("ij,ij->i", direction, e1), np.einsum("ij,ij->i", direction, e2)
        out[:, column] = along(np.stack([c * c, 2 * c * s, s * s], axis=1))
    a, b, d = tensor[:, 0], tensor[:, 1], tensor[:, 2]
    out[:, 3] = along(np.stack([d, -2 * b, a], axis=1))
    # the coefficients' unit is the ball radius: a curvature's variance per unit height noise in
    # cloud units is the fit's over unit^4 (height noise / unit, coefficient / unit), K's over unit^4 too
    # (its gradient is already in cloud units), the tilt's over unit^2
    out[:, :4] /= unit[:, None] ** 4
    if covariance.shape[1] == 5:
        out[:, 4] = (covariance[:, 3, 3] + covariance[:, 4, 4]) / (4.0 * unit**2)
    return out


def _principal_and_refined_normal(beta, unit, e1, e2, normals, tilt: bool):
    """One pass's curvatures and the normal its tilt terms correct.

    Parameters
    ----------
    beta : ndarray, shape (n, >= 3)
        Coefficients (tensor, tilt, cubic: see :mod:`heatcurv._kernels.chordfit`), in units of ``unit``.
    unit : ndarray, shape (n,)
        Each centre's ball radius (the length unit of the fit).
    e1, e2, normals : ndarray, shape (n, 3)
        The frame the fit was done in.
    tilt : bool
        Whether ``beta[:, 3:5]`` are the tilt coefficients.

    Returns
    -------
    pc : PrincipalCurvatures
        In the cloud's units (``well_posed`` not yet set).
    refined : ndarray, shape (n, 3)
        Unit normals corrected by the fitted tilt (``normals`` without tilt).
    """
    a, b, d = beta[:, 0] / unit, beta[:, 1] / unit, beta[:, 2] / unit
    pc = tensor_to_principal(0.5 * (a + d), 0.5 * (a - d), b, e1, e2, normals)
    return pc, _refined_normal(beta, e1, e2, normals, tilt)


def _refined_normal(beta, e1, e2, normals, tilt: bool):
    """Unit normals corrected by the fitted tilt, shape (n, 3) (``normals`` without tilt)."""
    if not tilt:
        return normals
    # coefficient of cos/r is -2 g_1 (and of sin/r, -2 g_2): the tangent plane is z = g . (x, y)
    g1, g2 = -0.5 * beta[:, 3], -0.5 * beta[:, 4]
    refined = normals - g1[:, None] * e1 - g2[:, None] * e2
    refined /= np.linalg.norm(refined, axis=1)[:, None]
    return refined


def _model_coefficients(beta: np.ndarray, tilt: bool, cubic: bool) -> np.ndarray:
    """The fitted shape columns as the nine of the full model (tensor, tilt, cubic), zeros where not fitted."""
    coefficients = np.zeros((beta.shape[0], 9))
    coefficients[:, :3] = beta[:, :3]
    if tilt:
        coefficients[:, 3:5] = beta[:, 3:5]
    if cubic:
        first = 3 + 2 * tilt
        coefficients[:, 5:9] = beta[:, first : first + 4]
    return coefficients


def _chord_fit_result(pc, well_posed, used, sigma2, covariance, beta, e1, e2, unit, coefficients,
                      noise2=None) -> ChordFit:
    """Assemble the :class:`ChordFit` of the last pass, back in the cloud's units.

    ``covariance``: the coefficients' covariance factors of :func:`noise_factors`; ``beta`` the
    coefficients (fit units); ``noise2`` the noise variance where it is not ``sigma2`` (fit units).
    """
    principal = PrincipalCurvatures(
        k1=pc.k1, k2=pc.k2, d1=pc.d1, d2=pc.d2, mean=pc.mean, gaussian=pc.gaussian, well_posed=well_posed
    )
    factors = noise_factors(covariance, beta[:, :3] / unit[:, None], pc.d1, pc.d2, e1, e2, unit)
    # report the normal the last fit was done in, so that d1 x d2 = n holds exactly; the
    # last tilt correction is below the measured normal error (0.001 deg on clean clouds)
    # back to the cloud's units: sigma scales with the radius
    return ChordFit(
        principal=principal, normals=used, sigma=np.sqrt(sigma2) * unit,
        noise=np.sqrt(sigma2 if noise2 is None else noise2) * unit, noise_factors=factors,
        coefficients=coefficients,
    )


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
    """Fit curvature tensor, normal tilt and cubic terms to the edge chord curvatures.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct (centred) points; ``nbhd.indices`` index them.
    nbhd : Neighbourhood
        Neighbour pairs, one row per centre.
    normals : ndarray, shape (m, 3)
        Unit, consistently oriented starting normals of the centres (PCA);
        the signs of all curvatures follow them.
    weights : ndarray, shape (nnz,)
        Pair weights, e.g. heat kernel times neighbour area ``W_ij A_j``.
    passes : int, optional
        Fits; each after the first starts from the normals the previous
        one's tilt corrected. 2 is enough (a third changed no measured
        digit).
    tilt, cubic : bool, optional
        Include the tilt and the cubic terms.
    denoise : bool, optional
        Fit heights with the denoised chord denominator and a centre offset
        (for noisy clouds) instead of the chord curvatures.
    centres : ndarray, shape (m, 3), optional
        The points the fits are centred on (default ``points``): a subset,
        such as the anchors of a wide kernel (:mod:`heatcurv.fits.anchors`).
    low_noise : bool, optional
        With ``denoise``: the denoised form's low-noise refit where a centre's residual
        allows it (:func:`_denoised_refit`; the caller's choice for a cloud in the
        very-low-noise band, :func:`heatcurv.fits.anchors.carry_degree`). Without it the
        denoised fit is the plain refit everywhere.

    Returns
    -------
    ChordFit

    Notes
    -----
    The per-pair sums run as compiled kernels without per-pair arrays
    (:mod:`heatcurv._kernels.chordfit`); this function runs the passes around
    them. Its numpy reference is ``tests/reference/chordfit.py``.
    """
    geometry = _fit_geometry(points, nbhd, weights, centres)
    nrm = np.ascontiguousarray(normals, dtype=np.float64)
    for _ in range(max(1, passes) - 1):
        nrm = _fit_pass(geometry, nrm, tilt, cubic, denoise, final=False)
    return _fit_pass(geometry, nrm, tilt, cubic, denoise, final=True, low_noise=low_noise)


def refine_normals(
    points: np.ndarray,
    nbhd: Neighbourhood,
    normals: np.ndarray,
    weights: np.ndarray,
    *,
    tilt: bool = True,
    cubic: bool = True,
    denoise: bool = False,
    centres: np.ndarray | None = None,
) -> np.ndarray:
    """The normals corrected by the tilt of one chord fit (the stage ``normal_refinement``).

    ``chord_fit(..., passes=2)`` is ``chord_fit(refine_normals(...), passes=1)``
    with the same arguments: the default estimator runs the two as named stages.

    Parameters
    ----------
    points, nbhd, normals, weights, tilt, cubic, denoise, centres
        As :func:`chord_fit`.

    Returns
    -------
    ndarray, shape (m, 3)
        Unit normals ``n - g_1 e_1 - g_2 e_2`` normalised, with the fitted tilt ``g``
        (the starting normals where ``tilt`` is False). With ``denoise`` the tilt
        is the plain height fit's: the denoised refit would move it by far less
        than the noise, at twice the cost.
    """
    geometry = _fit_geometry(points, nbhd, weights, centres)
    nrm = np.ascontiguousarray(normals, dtype=np.float64)
    return _fit_pass(geometry, nrm, tilt, cubic, denoise, final=False)


def _fit_geometry(points, nbhd: Neighbourhood, weights, centres) -> tuple:
    """The contiguous arrays every pass of the fit reads, and the unit of each centre."""
    if centres is None:
        centres = points
    points = np.ascontiguousarray(points, dtype=np.float64)
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    indptr = np.ascontiguousarray(nbhd.indptr, dtype=np.int64)
    indices = np.ascontiguousarray(nbhd.indices)  # int32 or int64: one compilation each
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    # Work in units of each centre's ball radius: every column of the design is then
    # of order one whatever the cloud's unit, so the solve (and its ridge) is
    # scale-free; curvatures are converted back at the end.
    unit = np.ascontiguousarray(nbhd.radius, dtype=np.float64)
    return points, centres, indptr, indices, weights, unit


def _fit_pass(base: tuple, nrm: np.ndarray, tilt: bool, cubic: bool, denoise: bool, final: bool,
              low_noise: bool = False):
    """One fit at the normals ``nrm``: the refined normals, or (``final``) the :class:`ChordFit`.

    Only the final pass's diagnostics are reported: earlier fits return their
    coefficients alone (no variance, no residual).
    """
    tilt, cubic = bool(tilt), bool(cubic)
    n_shape = 3 + 2 * tilt + 4 * cubic
    unit = base[-1]
    e1, e2 = tangent_frames(nrm)
    geometry = (*base, nrm, e1, e2, tilt, cubic)
    if not denoise:
        contrast = _noise_contrasts(n_shape, tilt) if final else None
        fitted = kernels.fit(kernels.CHORD, n_shape, geometry, contrast=contrast)
    elif final and low_noise:
        return _denoised_refit(geometry, n_shape, unit, e1, e2, nrm, tilt, cubic)
    else:
        # 1) plain height fit: z = z0 - r^2/2 * model;
        height_beta = kernels.fit(kernels.HEIGHT, n_shape + 1, geometry)
        if not final:
            # the tilt alone: the height fit's (the refit moves it by far less than the noise: noisy
            # spheres, ellipsoids, tori, patches and saddles gave the same errors to 0.01 points)
            return _refined_normal(height_beta[:, :n_shape], e1, e2, nrm, tilt)
        # 2) refit with the denoised chord denominator r^2 + (zhat - z0)^2 of its heights
        contrast = _noise_contrasts(n_shape + 1, tilt)
        fitted = kernels.fit(
            kernels.DENOISED_HEIGHT, n_shape + 1, geometry, height_beta=height_beta, contrast=contrast
        )
    if not final:
        return _refined_normal(fitted[:, :n_shape], e1, e2, nrm, tilt)
    beta, _, ok, covariance = fitted
    sigma2 = np.empty(nrm.shape[0])
    if denoise:
        kernels.weighted_height_residual(*geometry, kernels.DENOISED_HEIGHT, height_beta, beta, sigma2)
    else:
        kernels.weighted_height_residual(*geometry, kernels.CHORD, np.empty((0, n_shape)), beta, sigma2)
    pc, _ = _principal_and_refined_normal(beta[:, :n_shape], unit, e1, e2, nrm, tilt)
    # the normal this fit was done in, so that d1 x d2 = n holds exactly
    return _chord_fit_result(pc, ok, nrm, sigma2, covariance, beta, e1, e2, unit,
                             _model_coefficients(beta, tilt, cubic))


def _take_rows(geometry: tuple, rows: np.ndarray) -> tuple:
    """The fit geometry of the centres ``rows`` alone (their CSR pairs gathered)."""
    points, centres, indptr, indices, weights, unit, nrm, e1, e2, tilt, cubic = geometry
    counts = np.diff(indptr)[rows]
    sub_indptr = np.zeros(rows.size + 1, dtype=np.int64)
    np.cumsum(counts, out=sub_indptr[1:])
    pairs = np.repeat(indptr[:-1][rows] - sub_indptr[:-1], counts) + np.arange(sub_indptr[-1])
    return (
        points, np.ascontiguousarray(centres[rows]), sub_indptr, np.ascontiguousarray(indices[pairs]),
        np.ascontiguousarray(weights[pairs]), np.ascontiguousarray(unit[rows]), np.ascontiguousarray(nrm[rows]),
        np.ascontiguousarray(e1[rows]), np.ascontiguousarray(e2[rows]), tilt, cubic,
    )


def _denoised_refit(geometry, n_shape, unit, e1, e2, nrm, tilt, cubic) -> ChordFit:
    """The denoised fit under very low noise (``low_noise`` of :func:`chord_fit`), as the final :class:`ChordFit`.

    Very low noise (such as a LAZ file's millimetres) takes the ``LOW_NOISE_HEIGHT``
    refit: quartic terms, the denominator from a height fit with quartic terms
    (``QUARTIC_HEIGHT``), and pair weights ``w lambda^4 / (D^4 + lambda^4)`` with
    ``lambda^2 = sigma / TUNING.low_noise_sigma`` (``sigma`` that height fit's residual,
    units of the ball radius; at least ``LOW_NOISE_MIN_LAMBDA^2``), which weigh
    pairs nearer than ``lambda`` as the chord fit does (exact on circles) and
    farther ones as the height fit (whose heights the noise does not amplify). It is tried where the plain height fit's
    residual is below ``TUNING.low_noise_tried * TUNING.low_noise_limit * TUNING.low_noise_sigma`` and
    used where the quartic one's is below ``TUNING.low_noise_limit * TUNING.low_noise_sigma``;
    the other centres take ``DENOISED_HEIGHT``, as without ``low_noise``. The reported
    ``sigma`` of a low-noise centre is the plain height fit's residual (the quartic terms
    absorb the model error a clean cloud's residual consists of).

    The plain height fit is solved from the block of its columns in the quartic height fit's
    normal equations, which hold the same sums, and the two residuals come from one pass.
    """
    n = nrm.shape[0]
    p = n_shape + 1
    width = p + kernels.QUARTIC_COLUMNS
    limit2 = (TUNING.low_noise_limit * TUNING.low_noise_sigma) ** 2
    # 1) the height fits, plain and with quartic terms (the quartic one's residual is the noise: the plain
    #    one's holds the quartic shape, beyond the noise from about 200 neighbours on a torus; its heights
    #    are the refit's denominator)
    G, rhs, yy = kernels.normal_equations(kernels.QUARTIC_HEIGHT, width, geometry)
    plain = np.r_[np.arange(n_shape), width - 1]
    height_beta = kernels.solve_compiled(
        np.ascontiguousarray(G[:, plain][:, :, plain]), np.ascontiguousarray(rhs[:, plain]), yy, check=False
    )[0]
    quartic_beta = kernels.solve_compiled(G, rhs, yy, check=False, jacobi=True)[0]
    del G, rhs
    jet_sigma2, own = np.empty(n), np.empty(n)
    kernels.two_height_residuals(*geometry, height_beta, quartic_beta, jet_sigma2, own)
    beta = np.zeros((n, p))
    quartic = np.zeros((n, kernels.QUARTIC_COLUMNS))
    ok = np.zeros(n, dtype=bool)
    covariance = np.empty((n, 5 if tilt else 3, 5 if tilt else 3))
    sigma2 = jet_sigma2.copy()
    low = np.zeros(n, dtype=bool)
    # 2) the low-noise refit where both residuals allow it
    keep = (jet_sigma2 < TUNING.low_noise_tried**2 * limit2) & (own < limit2)
    rows = np.flatnonzero(keep)
    low[rows] = True
    if rows.size:
        sub = geometry if rows.size == n else _take_rows(geometry, rows)
        # lambda^4 = (sigma / TUNING.low_noise_sigma)^2, one more column of the height fit
        lam4 = np.maximum(own[rows] / TUNING.low_noise_sigma**2, kernels.LOW_NOISE_MIN_LAMBDA**4)
        hb = np.concatenate([quartic_beta[rows], lam4[:, None]], 1)
        fit_beta, _, fit_ok, fit_var = kernels.fit(
            kernels.LOW_NOISE_HEIGHT, width, sub, height_beta=hb, contrast=_noise_contrasts(width, tilt)
        )
        beta[rows, :n_shape] = fit_beta[:, :n_shape]
        beta[rows, n_shape] = fit_beta[:, -1]
        quartic[rows] = fit_beta[:, n_shape : n_shape + kernels.QUARTIC_COLUMNS]
        ok[rows], covariance[rows] = fit_ok, fit_var
    # 3) elsewhere the plain denoised refit, as without low_noise
    rows = np.flatnonzero(~low)
    if rows.size:
        sub = geometry if rows.size == n else _take_rows(geometry, rows)
        hb = np.ascontiguousarray(height_beta[rows])
        fit_beta, _, fit_ok, fit_var = kernels.fit(
            kernels.DENOISED_HEIGHT, p, sub, height_beta=hb, contrast=_noise_contrasts(p, tilt)
        )
        beta[rows], ok[rows], covariance[rows] = fit_beta, fit_ok, fit_var
        part = np.empty(rows.size)
        kernels.weighted_height_residual(*sub, kernels.DENOISED_HEIGHT, hb, fit_beta, part)
        sigma2[rows] = part
    pc, _ = _principal_and_refined_normal(beta[:, :n_shape], unit, e1, e2, nrm, tilt)
    # the quartic terms are part of the model the anchors carry (:mod:`heatcurv.fits.anchors`)
    coefficients = np.concatenate([_model_coefficients(beta, tilt, cubic), quartic], axis=1)
    # the noise at a low-noise centre: the quartic height fit's residual
    return _chord_fit_result(pc, ok, nrm, sigma2, covariance, beta, e1, e2, unit, coefficients,
                             noise2=np.where(low, own, sigma2))
