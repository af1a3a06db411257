"""The estimator's fit stages: the paper's tensor fit, the chord fit at every point, or at anchors.

Each function runs the named stages of one fit form (timed by the
:class:`~heatcurv.progress.StageClock` it is given) and returns a
:class:`Fitted`; which form runs is the :class:`~heatcurv.choice.plan.FitPlan`'s
choice (:func:`heatcurv.choice.plan.plan_fit`), made from the
:func:`kernel_choice`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from .choice.plan import FitPlan
from .choice.scale import ScaleReport, select_form, select_scale
from .fits.anchors import anchor_normals, anchor_rows, carry_fits, fit_anchors
from .fits.chordfit import ChordFit, chord_fit, refine_normals
from .fits.principal import PrincipalCurvatures, principal_fit
from .flags.border import border_points, centroid_offset
from .geometry.neighbourhood import BLOCK_PAIRS, block_ranges, knn_neighbourhood, rows_per_block
from .operators.areas import ball_area_factor, cut_ball_coverage, density_areas
from .operators.kernel import tapered_heat_weights
from .operators.mean_curvature import mean_curvature
from .operators.operator import HeatKernelOperator
from .orient.orientation import (
    Orientation,
    row_reach,
)
from .progress import StageClock
from .tuning import TUNING


@dataclass(frozen=True)
class Fitted:
    """What the method-specific stages produce, over the distinct points (operator order).

    ``wrapped`` (shape (m,), bool, or None where the plan does not assess it:
    :attr:`heatcurv.choice.plan.FitPlan.wrapped`) marks the points whose wide kernel's ball is round
    (``TUNING.round_ball``): the surface turns within it by about as much as it is wide, so it has no
    tangent plane a height fit could be taken over, and under that noise no narrower kernel resolves it
    either.
    """

    normals: np.ndarray
    mean: np.ndarray
    principal: PrincipalCurvatures
    areas: np.ndarray
    border: np.ndarray
    plan: FitPlan
    scale: ScaleReport | None = None
    residual: np.ndarray | None = None
    radius: np.ndarray | None = None
    orientation: Orientation | None = None
    width: np.ndarray | None = None
    support: np.ndarray | None = None
    mean_variance_factor: np.ndarray | None = None
    noise: np.ndarray | None = None
    noise_factors: np.ndarray | None = None
    wrapped: np.ndarray | None = None


def facing_viewpoint(fitted: Fitted, points: np.ndarray, towards: np.ndarray) -> Fitted:
    """``fitted`` with every normal facing ``towards`` (flipped with its curvatures where it did not)."""
    return turned_over(fitted, np.einsum("ij,ij->i", fitted.normals, towards - points) < 0)


def turned_over(fitted: Fitted, mask: np.ndarray) -> Fitted:
    """``fitted`` seen from the other side where ``mask`` (shape (m,), bool): normals and curvatures flipped."""
    if not mask.any():
        return fitted
    normals = np.where(mask[:, None], -fitted.normals, fitted.normals)
    pc = fitted.principal.flipped(mask)
    factors = fitted.noise_factors
    if factors is not None:  # k1 and k2 trade places where the side turns
        factors = np.where(mask[:, None], factors[:, [0, 2, 1, 3, 4]], factors)
    return replace(fitted, normals=normals, mean=pc.mean, principal=pc, noise_factors=factors)


def paper_fit_stages(op: HeatKernelOperator, plan: FitPlan, nrm: np.ndarray, K: np.ndarray, weights_areas: np.ndarray,
                      clock: StageClock) -> Fitted:
    """Stages ``mean``, ``principal`` and ``border`` of the paper's tensor fit (section 3).

    ``weights_areas``, shape (m,): the areas of the fit weights, 0 for outliers (no weight).
    """
    opts, X, nbhd = op.options, op.points, op.neighbourhood
    with clock.stage("mean"):
        mean = mean_curvature(K, nrm, opts.mean_formula)
    with clock.stage("principal"):
        # The paper's fit weights w_ij = W_ij |xi-xj|^2 A_j (section 3). Irregular
        # samples can give negative A_j; a least-squares objective with negative
        # weights has no minimum, so those neighbours get weight zero.
        pair_w = op.weights * nbhd.distances**2 * weights_areas[nbhd.indices]
        pc = principal_fit(X, nbhd, nrm, pair_w, mean=mean, constrained=plan.form == "paper-constrained")
        if plan.form == "paper-free":
            mean = pc.mean
    with clock.stage("border"):
        # border of open surfaces, on the neighbourhood the curvature was fitted on
        border = border_points(X, nbhd, nrm, taper=opts.taper)
    return Fitted(nrm, mean, pc, op.areas, border, plan)


def kernel_choice(op: HeatKernelOperator, nrm: np.ndarray, weights_areas: np.ndarray, keys: np.ndarray,
                   n_cloud: int, chosen=None):
    """Stage ``kernel_choice``: the noise and the chord fit's kernel widths (:mod:`heatcurv.choice.scale`).

    Parameters
    ----------
    op : HeatKernelOperator
    nrm : ndarray, shape (m, 3)
        Oriented starting normals.
    weights_areas : ndarray, shape (m,)
        The areas of the fit weights (0 for outliers).
    keys : ndarray, shape (m,)
        Sampling keys of the choice's subsample (:func:`heatcurv.geometry.sampling.geometric_keys`).
    n_cloud : int
        Rows of the whole cloud.
    chosen : heatcurv.choice.scale.ScaleChoice, optional
        The whole cloud's kernel widths (a tile's :class:`heatcurv.choice.choices.CloudChoices`);
        default: chosen here.

    Returns
    -------
    heatcurv.choice.scale.ScaleChoice
        With ``radius=``: the form alone (the operator's balls are the fit's).
    """
    opts, X = op.options, op.points
    tuning = opts.scale_tuning
    if opts.radius is not None:
        return select_form(X, op.neighbourhood, nrm, weights_areas, alpha=opts.alpha, n_sub=tuning.n_sub,
                           clean_ratio=tuning.clean_ratio, seed=tuning.seed, keys=keys)
    if chosen is not None:
        return chosen.at_points(X, opts.workers)
    return select_scale(
        X, op.tree, nrm, weights_areas, base_k=int(opts.neighbours), alpha=opts.alpha,
        fixed_k=None if opts.scale == "auto" else int(opts.scale), workers=opts.workers, keys=keys,
        n_cloud=n_cloud, **asdict(tuning),
    )


def point_fit_stages(
    op: HeatKernelOperator, plan: FitPlan, choice, nrm: np.ndarray, weights_areas: np.ndarray, clock: StageClock,
    rounded: bool = False,
) -> Fitted:
    """The chord fit (or, with ``radius=``, its denoised form) at every point, block by block.

    Parameters
    ----------
    op : HeatKernelOperator
    plan : FitPlan
        Not anchored.
    choice : heatcurv.choice.scale.ScaleChoice
        The kernel choice the plan was made from.
    nrm : ndarray, shape (m, 3)
        Oriented starting normals (kept when ``plan.keep_normals``).
    weights_areas : ndarray, shape (m,)
        The areas of the fit weights (0 for outliers: no weight in anyone's fit).
    clock : StageClock
    rounded : bool, optional
        The coordinates are rounded (:func:`heatcurv.flags.reliability.coordinate_rounding`): the
        variance factor also counts the centre point's own height error (:func:`_centre_gain`).

    Returns
    -------
    Fitted
        Normals refined by the fit's tilt (unless kept), the fitted curvatures,
        areas on the fit's kernel corrected by them, and border flags on the
        fit's ball.
    """
    opts, X, base = op.options, op.points, op.neighbourhood
    n = X.shape[0]
    keep_normals = plan.keep_normals
    fixed_radius = plan.radius is not None
    # the operator's neighbourhood already is the kernel's when the density ball holds k points
    reuse_base = fixed_radius or (opts.spacing == "density" and plan.k == int(opts.neighbours))
    # a kernel wider than the operator's counts its own density for the areas
    own_density = not fixed_radius and plan.k > opts.neighbours
    k = min(plan.k, n - 1)
    blocks = base.row_blocks(BLOCK_PAIRS) if fixed_radius else block_ranges(n, rows_per_block(k))

    areas, border, radius, residual = np.empty(n), np.empty(n, dtype=bool), np.empty(n), np.empty(n)
    centre = np.zeros(n)
    fits = []
    for lo, hi in blocks:
        centres = X[lo:hi]
        with clock.stage("fit_neighbourhood", report=False):
            nbhd = base.rows_slice(lo, hi) if reuse_base else knn_neighbourhood(
                X, k, tree=op.tree, queries=centres, workers=opts.workers
            )
        with clock.stage("fit_weights", report=False):
            # heat kernel, t = h^2 / 4 (eq 2.8) with h = R / alpha, tapered to 0 at the ball's edge
            weights = tapered_heat_weights(nbhd, nbhd.radius / opts.alpha, weights_areas)
        start = nrm[lo:hi]
        if not keep_normals:
            with clock.stage("normal_refinement", report=False):
                start = refine_normals(X, nbhd, start, weights, denoise=plan.denoise, centres=centres)
        with clock.stage("curvature_fit", report=False):
            fit = chord_fit(X, nbhd, start, weights, denoise=plan.denoise, centres=centres, passes=1)
        with clock.stage("border", report=False):
            offset = centroid_offset(X, nbhd, fit.normals, taper=opts.taper, centres=centres)
            border[lo:hi] = offset > TUNING.border_offset
        with clock.stage("area_correction", report=False):
            areas[lo:hi] = _corrected_areas(op, lo, hi, nbhd, fit, own_density, offset, reuse_base)
        radius[lo:hi] = nbhd.radius
        residual[lo:hi] = fit.sigma
        if rounded and not plan.denoise:
            centre[lo:hi] = _centre_gain(nbhd, weights)
        fits.append(fit)
        clock.report("fit", hi / n)
    fit = ChordFit.concatenate(fits)
    pc = fit.principal
    report = ScaleReport.from_choice(choice, plan.label, radius, opts.alpha, fixed_radius=fixed_radius, support=radius)
    factors = fit.noise_factors
    if rounded and not plan.denoise:
        # the centre's own height error shifts k1, k2 and the mean alike, and K = k1 k2 by (k1 + k2) times that
        factors = factors + np.column_stack([centre**2, centre**2, centre**2, (centre * (pc.k1 + pc.k2)) ** 2,
                                             np.zeros(n)])
    return Fitted(fit.normals, pc.mean, pc, areas, border, plan, report, residual, radius, support=radius,
                   mean_variance_factor=factors[:, 0], noise=fit.noise, noise_factors=factors)


def _centre_gain(nbhd, weights: np.ndarray) -> np.ndarray:
    """How much the chord fit's mean curvature moves per unit height error of its centre point, shape (rows,).

    The chord curvatures ``2 z_ij / |xi - xj|^2`` all share the centre's height
    error ``e``; the fit's isotropic term takes their weighted mean, so the mean
    curvature moves by about ``e * 2 sum_j w_ij / |xi - xj|^2 / sum_j w_ij``: the
    nearest neighbours dominate it (the denoised form fits an offset for it instead).
    """
    rows = nbhd.rows
    d2 = nbhd.distances**2
    near = np.bincount(rows, np.divide(weights, d2, out=np.zeros_like(d2), where=d2 > 0), nbhd.n_points)
    total = np.bincount(rows, weights, nbhd.n_points)
    return np.divide(2.0 * near, total, out=np.zeros_like(total), where=total > 0)


def anchored_fit_stages(
    op: HeatKernelOperator, plan: FitPlan, choice, nrm: np.ndarray, fit_areas: np.ndarray, keys: np.ndarray,
    clock: StageClock, mode: str, towards, outlier: np.ndarray, open_up: bool = False,
) -> Fitted:
    """The anchored fit: the wide kernel at anchors, carried to every point (:mod:`heatcurv.fits.anchors`).

    Stages ``anchor_fit``, ``carry`` and ``area_correction``, as ``plan`` says
    (anchors per ball, the anchors' own normals, the low-noise refit, the
    carry); ``choice`` is the kernel choice, ``fit_areas`` the areas weighting
    the fit (0 for outliers), ``keys`` the sampling keys the anchors are drawn
    by, ``mode`` and ``towards`` the orientation policy and its reference
    (:func:`heatcurv.normal_stages.viewpoint_reference`, or the policy's own axis) for the anchors' own
    normals, ``open_up`` whether ``"outward"`` was chosen by ``orient="auto"``. With
    :attr:`~heatcurv.choice.plan.FitPlan.anchor_normals` the result's orientation is the anchors'
    (:func:`heatcurv.fits.anchors.anchor_normals`).
    """
    opts, X = op.options, op.points
    n = X.shape[0]
    keep_normals = plan.keep_normals
    k_point = choice.k_per_point if choice.k_per_point is not None else np.full(n, choice.scale.k)
    with clock.stage("anchor_fit", report=False):
        index = anchor_rows(keys, k_point, opts.scale_tuning.seed, plan.anchors_per_ball)
    start, on_anchors, reoriented = nrm[index], None, None
    if plan.anchor_normals:
        with clock.stage("anchor_fit", report=False):
            on_anchors = anchor_normals(
                X, op.tree, index, k_point[index], fit_areas, mode=mode, towards=towards, excluded=outlier,
                alpha=opts.alpha, workers=opts.workers, open_up=open_up,
            )
        start = on_anchors.normals
    with clock.stage("anchor_fit", report=False):
        anchors = fit_anchors(
            X, op.tree, start, fit_areas, index, k_point[index], denoise=plan.denoise,
            low_noise=plan.refit, alpha=opts.alpha, taper=opts.taper,
            refine=not keep_normals, workers=opts.workers, progress=lambda f: clock.report("fit", 0.9 * f),
        )
    with clock.stage("carry", report=False):
        # the points' own normals keep each point to anchors on its side of a thin part (not under
        # strong noise, where they are what the anchors replace)
        carried = carry_fits(
            X, anchors, normals=nrm if keep_normals else None, reference=nrm if on_anchors is None else None,
            degree=plan.carry_degree,
            workers=opts.workers,
        )
        if on_anchors is not None:
            # the points' side is their nearest anchor's; so is an ambiguous one
            ambiguous = on_anchors.ambiguous[carried.nearest]
            report = replace(on_anchors.report, ambiguous=int(ambiguous.sum()), on_anchors=int(index.shape[0]))
            reach = None
            if on_anchors.reach is not None:
                # "up"/"viewpoint": a wall anchor's side was voted over the anchors' graph from anchors
                # up to on_anchors.reach away, so a point's side reads that far beyond its nearest anchor
                nearest = anchors.index[carried.nearest]
                own = np.linalg.norm(X - X[nearest], axis=1) + on_anchors.reach[carried.nearest]
                reach = row_reach(own, op.neighbourhood)
            reoriented = Orientation(carried.normals, ambiguous, report, reach)
    pc = carried.principal
    with clock.stage("area_correction", report=False):
        border = carried.offset > TUNING.border_offset
        areas = op.areas
        if opts.area_method == "density":
            # the anchors' area per point (their wide balls count a less noisy density), the ball's
            # curved area and a border point's cut share, as for the per-point fit
            areas = (carried.density_area * ball_area_factor(carried.radius, pc.k1, pc.k2)
                     * cut_ball_coverage(carried.offset, TUNING.border_offset))
    clock.report("fit", 1.0)
    report = ScaleReport.from_choice(choice, plan.label, carried.radius, opts.alpha, support=carried.support,
                                     anchors=index.shape[0], k=k_point)
    return Fitted(
        carried.normals, pc.mean, pc, areas, border, plan, report, carried.sigma, carried.radius, reoriented, k_point,
        carried.support, carried.mean_variance_factor, carried.noise, carried.noise_factors,
        wrapped=carried.roundness > TUNING.round_ball if plan.wrapped else None,
    )


def _corrected_areas(
    op: HeatKernelOperator, lo: int, hi: int, nbhd, fit: ChordFit, own_density: bool, offset: np.ndarray,
    same_ball: bool,
) -> np.ndarray:
    """Stage ``area_correction``: areas of points ``lo:hi`` on the fit's kernel, shape (hi - lo,).

    A kernel wider than the operator's counts its own, less noisy, density
    (:func:`heatcurv.operators.areas.density_areas`); either way the ball's curved area
    is corrected by the fitted curvatures (:func:`heatcurv.operators.areas.ball_area_factor`)
    and a border point's by the share of its ball the surface covers
    (:func:`heatcurv.operators.areas.cut_ball_coverage`, from the centroid ``offset`` on the
    fit's ball, which is the density's ball when ``own_density`` or
    ``same_ball``). The paper's areas (``H A = 1``) are kept as they are.
    """
    if op.options.area_method != "density":
        return op.areas[lo:hi]
    if own_density:
        own, area_radius = density_areas(nbhd), nbhd.radius
    else:
        own, area_radius = op.areas[lo:hi], op.neighbourhood.radius[lo:hi]
        if not same_ball:  # the density was counted on the operator's ball: its own offset
            base = op.neighbourhood.rows_slice(lo, hi)
            offset = centroid_offset(op.points, base, fit.normals, taper=op.options.taper, centres=op.points[lo:hi])
    coverage = cut_ball_coverage(offset, TUNING.border_offset)
    return own * ball_area_factor(area_radius, fit.principal.k1, fit.principal.k2) * coverage

