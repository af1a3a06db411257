"""``heatcurv.estimate``: every field of the paper's pipeline in one call, as a list of named stages.

Both methods share the operator and the normals::

    validate -> neighbours -> spacing -> areas            (heatcurv.operators.operator)
    -> kernel_check                                       (enough neighbours under the fit's kernel)
    -> outliers                                           (stray points and islands: unreliable, area 0)
    -> normals -> orientation                             (heatcurv.normal_stages: PCA or given; outward, up,
                                                           or to a viewpoint)
    -> mean_curvature_normal                              (K = L x, eq 2.10)

then the fit stages of :mod:`heatcurv.fit_stages`, for ``method="paper"`` (section 3)::

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
This module runs the stages in order and assembles the result (the reliability
flags of :mod:`heatcurv.flags` combined, every field in input order).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .backend import threads
from .choice.choices import frame_of
from .choice.kernel_check import check_ball_counts, check_kernel
from .choice.plan import noise_swamps_balls, plan_fit
from .fit_stages import (
    Fitted,
    anchored_fit_stages,
    facing_viewpoint,
    kernel_choice,
    paper_fit_stages,
    point_fit_stages,
    turned_over,
)
from .fits.uncertainty import StandardErrors, standard_errors
from .flags.outliers import Outliers, find_outliers
from .flags.reliability import (
    PrecisionReport,
    ReliabilityInputs,
    cloud_flags,
    coordinate_rounding,
    flattened,
    imprecise,
    precision_step,
    rounding_height_variance,
    rounding_uncertainty,
)
from .flags.sheets import facing_pairs, layered_sheet, second_sheet
from .geometry.sampling import geometric_keys
from .normal_stages import explained, normal_stages, orientation_mode, viewpoint_reference
from .operators.areas import fit_areas
from .operators.operator import HeatKernelOperator
from .options import resolve_options
from .orient.enclosure import warn_undecided
from .orient.orientation import Orientation, as_viewpoint, axisless_balls
from .orient.visibility import escaping_turns, own_layer
from .progress import StageClock
from .results import CurvatureResult
from .tuning import TUNING

__all__ = ["CurvatureResult", "estimate"]


def estimate(points, normals=None, *, method: str = "default", viewpoint=None, progress=None, choices=None,
             coordinate_precision=None, knn=None, **options):
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
    knn : callable, optional
        With ``choices``: the tile's neighbourhoods where they are known
        already (:meth:`heatcurv.operators.operator.HeatKernelOperator.from_points`,
        :mod:`heatcurv.tiles.neighbours`), and with them their areas and, if
        it has a method ``outliers(prepared)`` that returns
        :class:`~heatcurv.flags.outliers.Outliers` (or None), the outliers.
        Default: queried and computed.
    coordinate_precision : float or array_like of shape (3,), optional
        The step of the grid the coordinates were rounded to, input units,
        for all axes or one per axis (a LAS file's scale; 0: exact). Points
        whose curvature that rounding can move by more than
        ``TUNING.precision_tolerance`` of its size are not
        reliable; ``info["precision"]`` (a
        :class:`heatcurv.flags.reliability.PrecisionReport`) counts them. The
        standard errors hold the rounding as noise. Default:
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
        (+z) for an open surface over the horizontal plane, the same
        along its own axis for an open surface over another plane, and
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
    mode = orientation_mode(opts.orient, normals, viewpoint)
    if viewpoint is not None:
        as_viewpoint(viewpoint, len(points) if hasattr(points, "__len__") else None)  # fail before the work
    precision_step(coordinate_precision)  # fail before the work
    with threads(opts.workers):
        frame = None if choices is None else choices.frame
        op = HeatKernelOperator.from_points(points, opts, progress, frame, knn)  # validate, neighbours, spacing, areas
        rounding = coordinate_rounding(points, coordinate_precision)  # the points are valid now
        half_step = _stage_rounding(op, rounding)
        clock = StageClock(progress, dict(op.timings))
        with clock.stage("kernel_check"):
            frame = frame_of(op.prepared) if frame is None else frame
            # every subset a stage draws is drawn by these keys: no result depends on the row order
            keys = geometric_keys(op.points, op.neighbourhood, frame)
            check_kernel(op.neighbourhood, op.h, opts, keys)  # refuse a kernel that leaves nothing to fit
            check_ball_counts(op.points, op.tree, op.neighbourhood, op.h, opts, keys, op.prepared.unit)
        with clock.stage("outliers"):
            outliers = _known_outliers(knn, op)
            outliers = find_outliers(op.points, op.neighbourhood) if outliers is None else outliers
        towards = viewpoint_reference(op, mode, viewpoint)
        nrm, ball_shape, orientation, policy = normal_stages(op, normals, mode, towards, outliers.mask, clock,
                                                             keys, choices)
        mode = orientation.report.mode
        if policy is not None and policy.towards is not None:
            towards = policy.towards  # a sheet's own axis: the anchors' normals face it too
        with clock.stage("mean_curvature_normal"):
            K = op.mean_curvature_normal()
        # the areas of the fit weights W_ij A_j (the density areas are positive by construction)
        weights_areas = fit_areas(op.areas, outliers.mask)
        choice = None
        if opts.fit == "chord":
            with clock.stage("kernel_choice"):
                choice = kernel_choice(op, nrm, weights_areas, keys, frame.n_points,
                                        None if choices is None else choices.scale)
        # the one place that chooses the fit
        plan = plan_fit(opts, choice, keep_normals=normals is not None)
        if plan.form.startswith("paper"):
            fitted = paper_fit_stages(op, plan, nrm, K, weights_areas, clock)
        elif plan.anchored:
            fitted = anchored_fit_stages(op, plan, choice, nrm, weights_areas, keys, clock, mode, towards,
                                          outliers.mask, open_up=policy is not None)
            if fitted.orientation is not None:  # oriented again over the anchors (strong noise)
                orientation = fitted.orientation
        else:
            fitted = point_fit_stages(op, plan, choice, nrm, weights_areas, clock, rounded=rounding is not None)
        if mode == "viewpoint" and normals is None:
            # a scanner sees only surfaces facing it: the fit's refined normals must too
            fitted = facing_viewpoint(fitted, op.points, towards)
        errors = None
        if plan.standard_errors:
            with clock.stage("standard_errors"):
                errors = fit_standard_errors(op, fitted, weights_areas, keys, _value_reach(op, fitted, orientation),
                                             frame.n_points, half_step)
    orientation = replace(orientation, report=explained(orientation.report, policy, op.points.shape[0]))
    if orientation.report.undecided:
        warn_undecided(orientation.report.agreement, orientation.report.outside_share, stacklevel=3)
    return _result(op, fitted, ball_shape, K, orientation, outliers, clock.timings, whole_cloud=choices is None,
                   rounding=rounding, half_step=half_step, errors=errors, misfit_factor=plan.misfit_factor)


def fit_standard_errors(op: HeatKernelOperator, fitted: Fitted, weights_areas: np.ndarray, keys: np.ndarray,
                        reach: np.ndarray, cloud_points: int, half_step: np.ndarray | None = None) -> StandardErrors:
    """Stage ``standard_errors`` (:mod:`heatcurv.fits.uncertainty`) of the chord fit's values, operator order.

    ``reach``: how far each point's values reach (:func:`_value_reach`); ``cloud_points``: points of the
    whole cloud; ``half_step``: the largest rounding error of each point's coordinates
    (:func:`_stage_rounding`), None if they are exact.
    """
    n, opts, pc, plan = op.points.shape[0], op.options, fitted.principal, fitted.plan
    k = np.full(n, plan.k) if fitted.width is None else np.asarray(fitted.width)
    radius = op.neighbourhood.radius if fitted.radius is None else fitted.radius
    values = np.column_stack([pc.mean, pc.k1, pc.k2, pc.gaussian])
    return standard_errors(
        op.points, op.tree, weights_areas, fitted.normals, values, k, radius, keys, reach,
        cloud_points=cloud_points, denoise=plan.denoise,
        noise=fitted.noise, noise_factors=fitted.noise_factors, residual=fitted.residual, low_noise=plan.refit,
        alpha=opts.alpha,
        rounding=None if half_step is None else rounding_height_variance(half_step, fitted.normals),
        seed=opts.scale_tuning.seed, workers=opts.workers,
    )


def _reliability_inputs(op: HeatKernelOperator, fitted: Fitted, ball_shape, orientation: Orientation,
                        outliers: Outliers, areas: np.ndarray, coarse: np.ndarray | None = None) -> ReliabilityInputs:
    """Each distinct point's contribution to ``reliable`` (:mod:`heatcurv.flags.reliability`), shape (m,) each.

    ``coarse``: points whose coordinates are too coarse for their curvature (:func:`_precision`), or None.
    """
    nbhd, pc = op.neighbourhood, fitted.principal
    planarity, roundness = ball_shape
    local = ~nbhd.augmented & (planarity >= TUNING.planarity_min) & pc.well_posed & (areas > 0) & ~fitted.border
    local &= op.area_solve.converged & ~orientation.ambiguous & ~outliers.mask
    local &= ~_no_surface(fitted, axisless_balls(roundness, orientation.report.mode))
    if fitted.wrapped is not None:  # a wide kernel's ball round about the point: no tangent plane to fit over
        local &= ~fitted.wrapped
    if coarse is not None:
        local &= ~coarse
    if fitted.plan is not None and fitted.plan.flattening:
        local &= ~flattened(fitted.scale.sigma, nbhd.radius if fitted.radius is None else fitted.radius)
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


def _no_surface(fitted: Fitted, axisless: np.ndarray) -> np.ndarray:
    """Points whose ball has no normal axis and whose fit finds no surface either, shape (m,), bool.

    ``axisless``: :func:`heatcurv.orient.orientation.axisless_balls`, whose
    normal started from the reference direction. A noisy surface's ball can be as
    round, but its fit, over its own wider ball, leaves residuals of about the
    cloud's noise (the kernel choice's ``sigma``); a tree crown's scatter leaves
    ten times that or more (``TUNING.axisless_residual``). Without a residual
    or a noise level (the paper's fit) every such point counts.
    """
    if fitted.residual is None or fitted.scale is None:
        return axisless
    return axisless & ~(fitted.residual <= TUNING.axisless_residual * fitted.scale.sigma)


def _value_reach(op: HeatKernelOperator, fitted: Fitted, orientation: Orientation) -> np.ndarray:
    """How far each point's values reach, shape (m,), stage units: its fit's support, then the neighbours'
    normals and areas it weighs (one operator ball further, or as far as their sides were carried from:
    ``Orientation.reach`` of "up" and "viewpoint")."""
    radius = op.neighbourhood.radius
    support = radius if fitted.support is None else fitted.support
    near = radius if orientation.reach is None else np.maximum(radius, orientation.reach)
    return support + near


def _known_outliers(knn, op: HeatKernelOperator) -> Outliers | None:
    """The outliers ``knn`` knows of the operator's points (:func:`estimate`), None if it knows none."""
    known = getattr(knn, "outliers", None)
    return None if known is None or op.options.radius is not None else known(op.prepared)


def _stage_rounding(op: HeatKernelOperator, rounding) -> np.ndarray | None:
    """The largest rounding error of each distinct point's coordinates in the stages' unit, shape (m, 3) or (3,).

    ``rounding``: :func:`heatcurv.flags.reliability.coordinate_rounding` of the input (None: exact, returned).
    """
    if rounding is None:
        return None
    half_step, prepared = rounding[0], op.prepared
    # the rounding happened in the input's coordinates: a row's error is its own (before centring)
    return (half_step[prepared.first] if half_step.ndim == 2 else half_step) / prepared.unit


def _precision(op: HeatKernelOperator, fitted: Fitted, rounding, stage_step: np.ndarray | None) -> tuple:
    """The points too coarse for their curvature (or None) and ``info["precision"]``.

    The checks are :mod:`heatcurv.flags.reliability`'s.

    ``rounding``: :func:`heatcurv.flags.reliability.coordinate_rounding` of the input (None: exact coordinates,
    no report); ``stage_step``: the same per distinct point in the stages' unit (:func:`_stage_rounding`).
    """
    if rounding is None:
        return None, None
    half_step, source = rounding
    prepared, pc = op.prepared, fitted.principal
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


def _result(op: HeatKernelOperator, fitted: Fitted, ball_shape, K, orientation: Orientation, outliers: Outliers,
            timings, whole_cloud: bool = True, rounding=None, half_step: np.ndarray | None = None,
            errors: StandardErrors | None = None, misfit_factor: float | None = None):
    """The reliability flags, and every field back in the input order and unit (a :class:`CurvatureResult`).

    Outliers stand for no measured surface, and a point whose ball holds both sides of a thin
    part (:func:`heatcurv.flags.sheets.second_sheet`) for no one sheet: area 0, never reliable. The stages
    ran in the unit ``prepared.unit`` (a power of two, 1 for all but extreme
    extents): lengths are multiplied by it, curvatures divided, exactly. When
    the points are only a part of the cloud (``whole_cloud`` False), the flags
    that compare with the whole cloud's medians are left out of ``reliable``
    and their inputs returned in ``info["reliability"]`` (input order). ``rounding``: the input
    coordinates' rounding (:func:`_precision`; ``info["precision"]``), None if they are exact, and ``half_step``
    the same per distinct point in the stages' unit (:func:`_stage_rounding`). ``errors``:
    the standard errors (:mod:`heatcurv.fits.uncertainty`), None where not computed. ``misfit_factor``: the
    plan's (:attr:`heatcurv.choice.plan.FitPlan.misfit_factor`; None: a clean cloud's).
    """
    nbhd, prepared, pc = op.neighbourhood, op.prepared, fitted.principal
    unit = prepared.unit
    # a ball holding both sides of a thin part is no one sheet's neighbourhood: no area, and so not reliable
    sheets, pairs = _second_sheets(op, fitted, orientation, outliers, whole_cloud)
    areas = np.where(outliers.mask | sheets, 0.0, fitted.areas)
    coarse, precision = _precision(op, fitted, rounding, half_step)
    inputs = _reliability_inputs(op, fitted, ball_shape, orientation, outliers, areas, coarse)
    back = prepared.to_input_order
    if whole_cloud:
        reliable, resolution = cloud_flags(inputs, stacklevel=3, swamped=noise_swamps_balls(fitted.scale),
                                           misfit_factor=misfit_factor)
        extra = {}
        fitted, errors, orientation = _turned_to_escape(op, fitted, errors, orientation, ~reliable & ~outliers.mask,
                                                        timings)
        pc = fitted.principal
    else:
        reliable, resolution = inputs.local, float("nan")
        first = np.zeros(prepared.n_input, dtype=bool)
        first[prepared.first] = True  # medians count one row per set of duplicates
        extra = {"reliability": ReliabilityInputs(
            back(inputs.local), None if inputs.residual is None else back(inputs.residual), back(inputs.width),
            back(inputs.rho), back(inputs.counted) & first,
        )}
        # how far each point's values (and standard errors) reach, input units
        reach = _value_reach(op, fitted, orientation) if errors is None else errors.reach
        extra["reach"] = back(reach) * unit
        if orientation.patch is not None:  # "outward": what the winding number needs over the whole cloud
            extra["winding"] = _winding_inputs(prepared, orientation)
            extra["sheet_pairs"] = pairs
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
        **_standard_error_fields(errors, back, unit),
    )


def _winding_inputs(prepared, orientation: Orientation) -> dict:
    """A part of a cloud's ``info["winding"]``, input order and unit: what the winding number needs over the whole
    cloud (:func:`heatcurv.tiles.winding.tile_sources`)."""
    back, unit = prepared.to_input_order, prepared.unit
    # one row per set of duplicates is a source and carries the area
    source, weight = np.zeros(prepared.n_input, dtype=bool), np.zeros(prepared.n_input)
    source[prepared.first[orientation.sources]] = True
    weight[prepared.first] = orientation.weights * unit**2
    roundness = orientation.roundness
    if roundness is None:  # unknown, so no coarse cloud is rescued (heatcurv.orient.enclosure)
        roundness = np.full(orientation.normals.shape[0], np.nan)
    return {"patch": back(orientation.patch), "fine": back(orientation.fine), "source": source,
            "normals": back(orientation.normals), "weight": weight, "roundness": back(roundness)}


def _second_sheets(op: HeatKernelOperator, fitted: Fitted, orientation: Orientation, outliers: Outliers,
                   whole_cloud: bool):
    """The points whose ball holds two sheets (:func:`heatcurv.flags.sheets.second_sheet`), shape (m,), bool,
    and, for a part of a cloud oriented ``"outward"`` (a tile, whose normals' signs the driver settles), the
    pairs whose facing decides the rest (:func:`heatcurv.flags.sheets.facing_pairs`), else None.

    The pairs are input rows ``(p, q)`` with ``n_p . n_q`` as the part orients them, one per input row of
    ``p`` (duplicates alike) and the first input row of ``q``; the mask then holds the layered balls alone.
    """
    nbhd, prepared = op.neighbourhood, op.prepared
    if whole_cloud or orientation.patch is None:
        return second_sheet(op.points, fitted.normals, nbhd, op.h) & ~outliers.mask, None
    rows, columns, dots = facing_pairs(op.points, fitted.normals, nbhd, op.h)
    kept = ~outliers.mask[rows]
    rows, columns, dots = rows[kept], columns[kept], dots[kept]
    # every input row of p takes p's pairs
    counts = np.bincount(rows, minlength=prepared.n_distinct)[prepared.inverse]
    start = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=prepared.n_distinct))])[prepared.inverse]
    taken = np.repeat(start - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) + np.arange(counts.sum())
    pairs = (np.repeat(np.arange(prepared.n_input), counts), prepared.first[columns[taken]], dots[taken])
    return layered_sheet(op.points, fitted.normals, nbhd, op.h) & ~outliers.mask, pairs


def _turned_to_escape(op: HeatKernelOperator, fitted: Fitted, errors: StandardErrors | None,
                      orientation: Orientation, tested: np.ndarray, timings: dict):
    """``fitted``, ``errors`` and ``orientation`` with the ``tested`` points turned to where their rays escape.

    Only on a closed or undecided cloud (which has ``orientation.sources``), and not on its objects
    that are open on their own (``orientation.open``: they keep their sides).
    The occluders are the winding number's sources, discs across their
    fitted normals (:mod:`heatcurv.orient.visibility`), past the noise's layer
    where the kernel choice measured noise; the count goes to the report's
    ``escaped``, the time to the ``orientation`` stage.
    """
    source = orientation.sources
    if source is None:
        return fitted, errors, orientation
    if orientation.open is not None:
        tested = tested & ~orientation.open
    with StageClock(timings=timings).stage("orientation", report=False):
        layer = 0.0 if fitted.scale is None else own_layer(fitted.scale.sigma, fitted.scale.residual_rise)
        turn = escaping_turns(op.points, fitted.normals, tested, op.points[source], fitted.normals[source], layer)
    if errors is not None:  # k1 and k2 trade places where the side turns
        errors = replace(errors, k1=np.where(turn, errors.k2, errors.k1), k2=np.where(turn, errors.k1, errors.k2))
    report = replace(orientation.report, escaped=int(turn.sum()))
    return turned_over(fitted, turn), errors, replace(orientation, report=report)


def _standard_error_fields(errors: StandardErrors | None, back, unit: float) -> dict:
    """The result's ``*_se`` fields from ``errors`` (operator order, stage units), or {} without them."""
    if errors is None:
        return {}
    return {
        "mean_se": back(errors.mean) / unit, "k1_se": back(errors.k1) / unit, "k2_se": back(errors.k2) / unit,
        "gaussian_se": back(errors.gaussian) / unit**2, "normal_se": np.degrees(back(errors.normal)),
    }

