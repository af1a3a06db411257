"""``heatcurv.estimate``: every field of the paper's pipeline in one call, as a list of named stages.

Both methods share the operator and the normals::

    validate -> neighbours -> spacing -> areas            (heatcurv.operators.operator)
    -> kernel_check                                       (enough neighbours under the fit's kernel)
    -> outliers                                           (stray points and islands: unreliable, area 0)
    -> normals -> orientation                             (PCA; given; outward, up or to a viewpoint)
    -> mean_curvature_normal                              (K = L x, eq 2.10)

then ``method="paper"`` (section 3)::

    -> mean (eq 2.11 / 2.12) -> principal (tensor fit, eq 3.1) -> border

and ``method="default"`` (the chord fit, :mod:`heatcurv.fits.chordfit`)::

    -> kernel_choice                                      (noise and kernel width, heatcurv.choice.scale)
    -> the fit plan                                       (heatcurv.choice.plan: the one place that chooses)
    -> at every point, per block of points:
         fit_neighbourhood -> fit_weights -> normal_refinement
         -> curvature_fit -> border -> area_correction
       or at anchors (noise, or a kernel wider than k_fit; heatcurv.fits.anchors):
         anchor_fit -> carry -> area_correction

Each stage is timed under its own name (``result.info["timings"]``; the
command line's ``--verbose``); :mod:`heatcurv.progress` lists them. The default
method's fit runs block by block so that its own, wider neighbourhood exists
only one block at a time; its stages report progress together as ``"fit"``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from .backend import threads
from .choice.choices import frame_of
from .choice.kernel_check import check_ball_counts, check_kernel
from .choice.plan import FitPlan, plan_fit
from .choice.scale import ScaleReport, centre_noise, select_form, select_scale
from .errors import HeatcurvError
from .fits.anchors import anchor_normals, anchor_rows, carry_fits, fit_anchors
from .fits.chordfit import ChordFit, chord_fit, refine_normals
from .fits.mean_curvature import mean_curvature
from .fits.principal import PrincipalCurvatures, principal_fit
from .flags.border import border_points, centroid_offset
from .flags.outliers import Outliers, find_outliers
from .flags.reliability import (
    PrecisionReport,
    ReliabilityInputs,
    cloud_flags,
    coordinate_rounding,
    imprecise,
    precision_step,
    rounding_uncertainty,
)
from .flags.sheets import second_sheet
from .geometry.neighbourhood import BLOCK_PAIRS, block_ranges, knn_neighbourhood, rows_per_block
from .geometry.normals import pca_normals
from .geometry.sampling import geometric_keys, key_sample
from .geometry.validation import prepare_normals
from .operators.areas import ball_area_factor, cut_ball_coverage, density_areas, fit_areas
from .operators.kernel import tapered_heat_weights
from .operators.operator import HeatKernelOperator
from .options import resolve_options
from .orient.enclosure import warn_undecided
from .orient.orientation import AutoPolicy, Orientation, OrientationReport, as_viewpoint, auto_policy, orient, row_reach
from .progress import StageClock
from .results import CurvatureResult
from .tuning import TUNING

__all__ = ["CurvatureResult", "estimate"]



@dataclass(frozen=True)
class _Fitted:
    """What the method-specific stages produce, over the distinct points (operator order)."""

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


def estimate(points, normals=None, *, method: str = "default", viewpoint=None, progress=None, choices=None,
             coordinate_precision=None, **options):
    """Normals, mean, Gaussian and principal curvatures, directions and areas of a point cloud.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Point coordinates, any unit, any position (they are centred first).
        Exact duplicates are computed once and get their twin's values.
    normals : array_like, shape (n, 3), optional
        Normals to use instead of the estimated ones; curvature signs follow
        them. Need not be unit length.
    method : {"default", "paper"}, optional
        ``"paper"`` follows the paper literally (eq 2.6 spacing, alpha = 4,
        m = 1/4, areas from ``H A = 1``, mean curvature ``1/2 |K|`` of
        eq 2.11, constrained fit of eq 3.1): the reproducible reference,
        accurate on regular samples only. ``"default"`` is accurate on
        irregular, scanned and noisy clouds: spacing from the density (the
        ball holds 60 neighbours), density areas, and the chord fit with tilt
        and cubic terms at a kernel chosen from the measured noise. Every
        option overrides the preset (``heatcurv.METHODS`` lists both).
    viewpoint : array_like, shape (3,) or (n, 3), optional
        Sensor position, or one per point (scanner positions), in the input
        coordinates: every estimated normal faces it (``orient="viewpoint"``,
        implied).
    progress : callable, optional
        Called as ``progress(stage, fraction)`` as the stages run
        (:mod:`heatcurv.progress`); the command line's progress bars use it.
    choices : heatcurv.choice.choices.CloudChoices, optional
        When ``points`` are a part of a larger cloud (a tile with its halo,
        :mod:`heatcurv.tiles`): the whole cloud's frame and kernel widths, so
        that the part's points get the values the whole cloud would give them.
        ``reliable`` then leaves out the two flags that compare a point with
        medians over the whole cloud (:mod:`heatcurv.flags.reliability`):
        ``info["reliability"]`` holds their inputs and ``info["reach"]`` how
        far each point's values reach (input units); oriented outward,
        ``info["winding"]`` what the winding number needs over the whole
        cloud (:mod:`heatcurv.tiles.winding`): each point's patch, whether it
        is a source, its normal as the spanning tree oriented it and its
        weight (area, input units; on one row of a set of duplicates).
        Default: made from ``points``.
    coordinate_precision : float or array_like of shape (3,), optional
        The step of the grid the coordinates were rounded to, input units,
        for all axes or one per axis (a LAS file's scale; 0: exact). Points
        whose curvature that rounding can move by more than
        ``TUNING.precision_tolerance`` of its size are not
        reliable; ``info["precision"]`` (a
        :class:`heatcurv.flags.reliability.PrecisionReport`) counts them. Default:
        from the type of ``points``: float32 coordinates (and float64 ones
        float32 holds exactly) are rounded to float32's spacing, other
        float64 coordinates are exact (:func:`heatcurv.flags.reliability.coordinate_rounding`).
    **options
        Any field of :class:`heatcurv.Options`, where each is documented once:
        ``alpha`` (ball radius ``r = alpha h``; paper 4, default 2), ``m``
        (``t = m h^2``, 1/4), ``spacing`` (``"global"`` eq 2.6, ``"local"``
        eq 2.7, ``"density"``), ``gamma`` and ``k_local`` (eq 2.7),
        ``neighbours`` (density ball and narrowest fit kernel, 60),
        ``area_method`` (``"system"`` ``H A = 1`` or ``"density"``),
        ``mean_formula`` (``"norm"`` eq 2.11 or ``"projection"`` eq 2.12),
        ``fit`` (``"chord"``, ``"constrained"`` eq 3.1, ``"unconstrained"``),
        ``scale`` (``"auto"`` or a neighbour count; ``res.info["scale"]``
        reports the choice), ``scale_tuning`` (:class:`heatcurv.ScaleTuning`),
        ``orient`` (which side the normals point to: ``"auto"``, the
        default, is ``"viewpoint"`` when a viewpoint is given, else ``"up"``
        (+z) for an open surface over the horizontal plane and
        ``"outward"`` for anything else; ``info["orientation"].reason``
        says which; :mod:`heatcurv.orient.orientation`),
        ``area_solver``, ``taper``, ``min_neighbours`` (6) and ``workers``
        (threads; -1: all cores).

    Returns
    -------
    CurvatureResult

    Raises
    ------
    HeatcurvError
        On bad input (shape, NaN/inf, too few points, collinear or coincident
        points) or bad options, with a message naming the problem.

    Examples
    --------
    >>> import numpy as np, heatcurv
    >>> sphere = heatcurv.surfaces.Sphere(radius=2.0).sample(4000, "fibonacci")
    >>> res = heatcurv.estimate(sphere.points)
    >>> bool(abs(np.median(res.mean) - 0.5) < 0.01)
    True
    """
    opts = resolve_options(method, **options)
    mode = _orientation_mode(opts.orient, normals, viewpoint)
    if viewpoint is not None:
        as_viewpoint(viewpoint, len(points) if hasattr(points, "__len__") else None)  # fail before the work
    precision_step(coordinate_precision)  # fail before the work
    with threads(opts.workers):
        frame = None if choices is None else choices.frame
        op = HeatKernelOperator.from_points(points, opts, progress, frame)  # validate, neighbours, spacing, areas
        rounding = coordinate_rounding(points, coordinate_precision)  # the points are valid now
        clock = StageClock(progress, dict(op.timings))
        with clock.stage("kernel_check"):
            frame = frame_of(op.prepared) if frame is None else frame
            # every subset a stage draws is drawn by these keys: no result depends on the row order
            keys = geometric_keys(op.points, op.neighbourhood, frame)
            check_kernel(op.neighbourhood, op.h, opts, keys)  # refuse a kernel that leaves nothing to fit
            check_ball_counts(op.points, op.tree, op.neighbourhood, op.h, opts, keys, op.prepared.unit)
        with clock.stage("outliers"):
            outliers = find_outliers(op.points, op.neighbourhood)
        towards = _reference(op, mode, viewpoint)
        nrm, ball_shape, orientation, policy = _normal_stages(op, normals, mode, towards, outliers.mask, clock,
                                                             keys, choices)
        mode = orientation.report.mode
        with clock.stage("mean_curvature_normal"):
            K = op.mean_curvature_normal()
        # the areas of the fit weights W_ij A_j (the density areas are positive by construction)
        weights_areas = fit_areas(op.areas, outliers.mask)
        choice = None
        if opts.fit == "chord":
            with clock.stage("kernel_choice"):
                choice = _kernel_choice(op, nrm, weights_areas, keys, frame.n_points,
                                        None if choices is None else choices.scale)
        plan = plan_fit(opts, choice, keep_normals=normals is not None)  # the one place that chooses the fit
        if plan.form.startswith("paper"):
            fitted = _paper_fit_stages(op, plan, nrm, K, weights_areas, clock)
        elif plan.anchored:
            fitted = _anchored_fit_stages(op, plan, choice, nrm, weights_areas, keys, clock, mode, towards,
                                          outliers.mask)
            if fitted.orientation is not None:  # oriented again over the anchors (strong noise)
                orientation = fitted.orientation
        else:
            fitted = _point_fit_stages(op, plan, choice, nrm, weights_areas, clock, rounded=rounding is not None)
        if mode == "viewpoint" and normals is None:
            # a scanner sees only surfaces facing it: the fit's refined normals must too
            fitted = _facing_viewpoint(fitted, op.points, towards)
    orientation = replace(orientation, report=_explained(orientation.report, policy, op.points.shape[0]))
    if orientation.report.undecided:
        warn_undecided(orientation.report.agreement, orientation.report.outside_share, stacklevel=3)
    return _result(op, fitted, ball_shape, K, orientation, outliers, clock.timings, whole_cloud=choices is None,
                   rounding=rounding)


def _orientation_mode(orient_option: str, normals, viewpoint) -> str:
    """The orientation policy of this call: ``"given"``, ``"outward"``, ``"up"``, ``"viewpoint"``, or ``"auto"``.

    ``"auto"`` (no viewpoint, no normals) is decided on the cloud's sample by :func:`_auto_policy`.
    """
    if normals is not None:
        if viewpoint is not None:
            raise HeatcurvError("give either normals or a viewpoint, not both")
        if orient_option != "auto":
            raise HeatcurvError(f"orient={orient_option!r} orients estimated normals; the given normals are kept "
                                "as they are (leave orient='auto')")
        return "given"
    if orient_option == "auto":
        return "auto" if viewpoint is None else "viewpoint"
    if orient_option == "viewpoint" and viewpoint is None:
        raise HeatcurvError("orient='viewpoint' needs viewpoint=(x, y, z), the scanner's position")
    if orient_option != "viewpoint" and viewpoint is not None:
        raise HeatcurvError(f"a viewpoint orients the normals towards the scanner; it cannot be combined with "
                            f"orient={orient_option!r}")
    return orient_option


def _auto_policy(op: HeatKernelOperator, keys: np.ndarray, choices, normals: np.ndarray,
                 outlier: np.ndarray) -> AutoPolicy:
    """``orient="auto"`` without a viewpoint: ``"up"`` or ``"outward"``.

    :func:`heatcurv.orient.orientation.auto_policy` decides.

    Decided on the scale choice's sample centres (the ``n_sub`` points of
    smallest keys) and the noise the choice measures there
    (:func:`heatcurv.choice.scale.centre_noise`: the same fit the choice makes
    next, on the unoriented ``normals``, shape (m, 3), with no weight on the
    ``outlier`` points, shape (m,), bool), or taken from ``choices`` (a tiled
    run's survey decided it on the same centres of the whole cloud, with the
    choice's ``sigma``).
    """
    if choices is not None and getattr(choices, "orientation", None) is not None:
        return choices.orientation
    opts = op.options
    tuning = opts.scale_tuning
    noise = centre_noise(op.points, op.tree, normals, fit_areas(op.areas, outlier), base_k=int(opts.neighbours),
                         alpha=opts.alpha, n_sub=tuning.n_sub, seed=tuning.seed, keys=keys, workers=opts.workers)
    return auto_policy(op.points[key_sample(keys, tuning.n_sub, tuning.seed)], noise)


def _explained(report: OrientationReport, policy: AutoPolicy | None, n: int) -> OrientationReport:
    """``report`` with its reason (auto "up": and its convention).

    The reason is :attr:`~heatcurv.orient.orientation.OrientationReport.reason`.
    """
    if report.mode == "given":
        return replace(report, reason="the given normals, as they are")
    if report.mode == "viewpoint":
        return replace(report, reason="towards the viewpoint")
    if report.mode == "up":
        if policy is None:
            return replace(report, reason="orient='up': towards +z")
        # turning the cloud may change the choice
        return replace(report, reason=policy.reason, by_convention=n, policy=policy)
    if report.closed:
        why = "encloses a volume: away from it (winding number)"
    elif report.undecided:
        why = ("may or may not enclose a volume: the winding number's sides, every point flagged "
               "(too few points across its thin parts, or an open scene)")
    elif report.closed is None:
        why = "outward: each piece as the tree orients it (a part of a cloud)"
    else:
        why = "open: each component's outward vote, its convex side out"
        if report.by_convention:
            why += "; nearly flat components by the least-variance-axis convention"
    return replace(report, reason=why if policy is None else f"{policy.reason}; {why}", policy=policy)


def _reference(op: HeatKernelOperator, mode: str, viewpoint):
    """What ``"viewpoint"`` orients towards, in the operator's (centred, distinct) frame; None otherwise."""
    if mode != "viewpoint":
        return None
    prepared = op.prepared
    v = as_viewpoint(viewpoint, prepared.n_input)
    return ((v if v.ndim == 1 else v[prepared.first]) - prepared.offset) / prepared.unit


def _normal_stages(op: HeatKernelOperator, given, mode: str, towards, outlier: np.ndarray, clock: StageClock,
                   keys: np.ndarray, choices=None):
    """Stages ``normals`` and ``orientation``: oriented unit normals, the balls' PCA shape and the orientation.

    ``mode="auto"`` is decided first (:func:`_auto_policy`). Outliers get no
    weight in the outward vote (one far point would drag the centroid). Given
    ``choices`` (a part of a cloud), the winding number is not run here: the
    orientation's patches are cut for :mod:`heatcurv.tiles.winding`.

    Returns
    -------
    normals : ndarray, shape (m, 3)
    ball_shape : tuple of ndarray, shape (m,) each
        The balls' PCA planarity and roundness (:func:`heatcurv.geometry.normals.pca_normals`; 1 and NaN
        for given normals).
    orientation : Orientation
    policy : AutoPolicy or None
        What ``"auto"`` chose, None for the other modes.
    """
    X, nbhd, prepared = op.points, op.neighbourhood, op.prepared
    if given is not None:
        with clock.stage("normals"):
            nrm = prepare_normals(given, prepared)
        kept = Orientation(nrm, np.zeros(X.shape[0], dtype=bool), OrientationReport("given"))
        return nrm, (np.ones(X.shape[0]), np.full(X.shape[0], np.nan)), kept, None
    with clock.stage("normals"):
        nrm, planarity, roundness = pca_normals(X, nbhd, taper=op.options.taper, roundness=True)
    with clock.stage("orientation"):
        policy = _auto_policy(op, keys, choices, nrm, outlier) if mode == "auto" else None
        orientation = orient(X, nrm, nbhd, op.areas, mode=mode if policy is None else policy.mode, towards=towards,
                             excluded=outlier, whole_cloud=choices is None,
                             cloud_points=None if choices is None else choices.frame.n_points)
    return orientation.normals, (planarity, roundness), orientation, policy


def _facing_viewpoint(fitted: _Fitted, points: np.ndarray, towards: np.ndarray) -> _Fitted:
    """``fitted`` with every normal facing ``towards`` (flipped with its curvatures where it did not)."""
    away = np.einsum("ij,ij->i", fitted.normals, towards - points) < 0
    if not away.any():
        return fitted
    normals = np.where(away[:, None], -fitted.normals, fitted.normals)
    pc = fitted.principal.flipped(away)
    return replace(fitted, normals=normals, mean=pc.mean, principal=pc)


def _paper_fit_stages(op: HeatKernelOperator, plan: FitPlan, nrm: np.ndarray, K: np.ndarray, weights_areas: np.ndarray,
                      clock: StageClock) -> _Fitted:
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
    return _Fitted(nrm, mean, pc, op.areas, border, plan)


def _kernel_choice(op: HeatKernelOperator, nrm: np.ndarray, weights_areas: np.ndarray, keys: np.ndarray,
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


def _point_fit_stages(
    op: HeatKernelOperator, plan: FitPlan, choice, nrm: np.ndarray, weights_areas: np.ndarray, clock: StageClock,
    rounded: bool = False,
) -> _Fitted:
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
    _Fitted
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
    return _Fitted(fit.normals, pc.mean, pc, areas, border, plan, report, residual, radius, support=radius,
                   mean_variance_factor=fit.mean_variance_factor + centre**2)


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


def _anchored_fit_stages(
    op: HeatKernelOperator, plan: FitPlan, choice, nrm: np.ndarray, fit_areas: np.ndarray, keys: np.ndarray,
    clock: StageClock, mode: str, towards, outlier: np.ndarray,
) -> _Fitted:
    """The anchored fit: the wide kernel at anchors, carried to every point (:mod:`heatcurv.fits.anchors`).

    Stages ``anchor_fit``, ``carry`` and ``area_correction``, as ``plan`` says
    (anchors per ball, the anchors' own normals, the low-noise refit, the
    carry); ``choice`` is the kernel choice, ``fit_areas`` the areas weighting
    the fit (0 for outliers), ``keys`` the sampling keys the anchors are drawn
    by, ``mode`` and ``towards`` the orientation policy and its reference
    (:func:`_reference`) for the anchors' own normals. With :attr:`~heatcurv.choice.plan.FitPlan.anchor_normals`
    the result's orientation is the anchors' (:func:`heatcurv.fits.anchors.anchor_normals`).
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
                alpha=opts.alpha, workers=opts.workers,
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
    return _Fitted(
        carried.normals, pc.mean, pc, areas, border, plan, report, carried.sigma, carried.radius, reoriented, k_point,
        carried.support, carried.mean_variance_factor,
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


def _reliability_inputs(op: HeatKernelOperator, fitted: _Fitted, ball_shape, orientation: Orientation,
                        outliers: Outliers, areas: np.ndarray, coarse: np.ndarray | None = None) -> ReliabilityInputs:
    """Each distinct point's contribution to ``reliable`` (:mod:`heatcurv.flags.reliability`), shape (m,) each.

    ``coarse``: points whose coordinates are too coarse for their curvature (:func:`_precision`), or None.
    """
    nbhd, pc = op.neighbourhood, fitted.principal
    planarity, roundness = ball_shape
    local = ~nbhd.augmented & (planarity >= TUNING.planarity_min) & pc.well_posed & (areas > 0) & ~fitted.border
    local &= op.area_solve.converged & ~orientation.ambiguous & ~outliers.mask
    if coarse is not None:
        local &= ~coarse
    m = op.points.shape[0]
    width = np.zeros(m, dtype=np.int64) if fitted.width is None else np.asarray(fitted.width, dtype=np.int64)
    # the median point's sampling spacing s = R sqrt(pi / count) in radii of curvature
    counts = np.maximum(nbhd.counts, 1)
    with np.errstate(invalid="ignore", over="ignore"):
        rho = nbhd.radius * np.sqrt(np.pi / counts) * np.maximum(np.abs(pc.k1), np.abs(pc.k2))
    # a round ball holds a tube, not a disc: its fitted curvature is no measure of the sampling
    rho = np.where(roundness > TUNING.round_ball, np.inf, rho)
    residual = None if fitted.residual is None else fitted.residual / op.h
    return ReliabilityInputs(local, residual, width, rho, ~outliers.mask)


def _precision(op: HeatKernelOperator, fitted: _Fitted, rounding) -> tuple:
    """The points too coarse for their curvature (or None) and ``info["precision"]``.

    The checks are :mod:`heatcurv.flags.reliability`'s.

    ``rounding``: :func:`heatcurv.flags.reliability.coordinate_rounding` of the input (None: exact coordinates,
    no report).
    """
    if rounding is None:
        return None, None
    half_step, source = rounding
    prepared, pc = op.prepared, fitted.principal
    # the rounding happened in the input's coordinates: a row's error is its own (before centring)
    stage_step = (half_step[prepared.first] if half_step.ndim == 2 else half_step) / prepared.unit
    largest = float(np.max(half_step))
    rule = (f"{TUNING.precision_coverage:g} x the mean curvature's standard deviation under the rounding above "
            f"{TUNING.precision_tolerance:.0%} of the point's largest |k1|, |k2|")
    if fitted.mean_variance_factor is None:
        n = prepared.n_input
        reason = f"{source}, errors up to {largest:.3g}: not assessed by method='paper' (the chord fit's only)"
        return None, PrecisionReport(source, largest, 0, np.full(n, np.nan), reason)
    uncertainty = rounding_uncertainty(stage_step, fitted.normals, fitted.mean_variance_factor)
    radius = op.neighbourhood.radius if fitted.radius is None else fitted.radius
    coarse = imprecise(uncertainty, pc.k1, pc.k2, radius)
    flagged = int(np.count_nonzero(prepared.to_input_order(coarse)))
    reason = (f"{source}, errors up to {largest:.3g}: {flagged} point(s) unreliable, where {rule} "
              "(or of a nearly flat point's ball)")
    return coarse, PrecisionReport(source, largest, flagged, prepared.to_input_order(uncertainty) / prepared.unit,
                                   reason)


def _result(op: HeatKernelOperator, fitted: _Fitted, ball_shape, K, orientation: Orientation, outliers: Outliers,
            timings, whole_cloud: bool = True, rounding=None):
    """The reliability flags, and every field back in the input order and unit (a :class:`CurvatureResult`).

    Outliers stand for no measured surface, and a point whose ball holds both sides of a thin
    part (:func:`heatcurv.flags.sheets.second_sheet`) for no one sheet: area 0, never reliable. The stages
    ran in the unit ``prepared.unit`` (a power of two, 1 for all but extreme
    extents): lengths are multiplied by it, curvatures divided, exactly. When
    the points are only a part of the cloud (``whole_cloud`` False), the flags
    that compare with the whole cloud's medians are left out of ``reliable``
    and their inputs returned in ``info["reliability"]`` (input order). ``rounding``: the input
    coordinates' rounding (:func:`_precision`; ``info["precision"]``), None if they are exact.
    """
    nbhd, prepared, pc = op.neighbourhood, op.prepared, fitted.principal
    unit = prepared.unit
    # a ball holding both sides of a thin part is no one sheet's neighbourhood: no area, and so not reliable
    sheets = second_sheet(op.points, fitted.normals, nbhd, op.h) & ~outliers.mask
    areas = np.where(outliers.mask | sheets, 0.0, fitted.areas)
    coarse, precision = _precision(op, fitted, rounding)
    inputs = _reliability_inputs(op, fitted, ball_shape, orientation, outliers, areas, coarse)
    back = prepared.to_input_order
    if whole_cloud:
        reliable, resolution = cloud_flags(inputs, stacklevel=3)
        extra = {}
    else:
        reliable, resolution = inputs.local, float("nan")
        first = np.zeros(prepared.n_input, dtype=bool)
        first[prepared.first] = True  # medians count one row per set of duplicates
        extra = {"reliability": ReliabilityInputs(
            back(inputs.local), None if inputs.residual is None else back(inputs.residual), back(inputs.width),
            back(inputs.rho), back(inputs.counted) & first,
        )}
        # how far each point's values reach: its fit's support, then the neighbours' normals and
        # areas it weighs (one operator ball further, or as far as their sides were carried from:
        # Orientation.reach of "up" and "viewpoint"), input units
        support = nbhd.radius if fitted.support is None else fitted.support
        near = nbhd.radius if orientation.reach is None else np.maximum(nbhd.radius, orientation.reach)
        extra["reach"] = back(support + near) * unit
        if orientation.patch is not None:  # "outward": what the winding number needs over the whole cloud
            # one row per set of duplicates is a source and carries the area
            source, weight = np.zeros(prepared.n_input, dtype=bool), np.zeros(prepared.n_input)
            source[prepared.first[orientation.sources]] = True
            weight[prepared.first] = orientation.weights * unit**2
            extra["winding"] = {"patch": back(orientation.patch), "source": source,
                                "normals": back(orientation.normals), "weight": weight}
    info = {
        "n_distinct": prepared.n_distinct, "area_solve": op.area_solve, "orientation": orientation.report,
        "outliers": outliers.count, "second_sheet": int(np.count_nonzero(sheets)), "resolution": resolution,
        **extra,
    }
    if precision is not None:
        info["precision"] = precision
    info["plan"] = fitted.plan
    if fitted.scale is not None:
        info["scale"] = fitted.scale.in_unit(unit)
    info["timings"] = timings
    return CurvatureResult(
        normals=back(fitted.normals),
        mean=back(fitted.mean) / unit,
        gaussian=back(pc.gaussian) / unit**2,
        k1=back(pc.k1) / unit,
        k2=back(pc.k2) / unit,
        d1=back(pc.d1),
        d2=back(pc.d2),
        area=prepared.share_among_duplicates(areas) * unit**2,
        outlier=back(outliers.mask),
        reliable=back(reliable),
        border=back(fitted.border),
        spacing=back(op.h) * unit,
        neighbours=back(nbhd.counts),
        mean_curvature_normal=back(K) / unit,
        options=op.options,
        info=info,
        fit_radius=back(nbhd.radius if fitted.radius is None else fitted.radius) * unit,
    )
