"""The ONE place a tiled run calls the numerical core: survey a tile, merge the surveys, compute a tile.

The driver (:mod:`.driver`) and the tasks (:mod:`.tasks`) call nothing else of
the core. A tile computes as the whole cloud would
because every choice that is not a point's own is made once
(:mod:`heatcurv.choice.choices`):

* the **frame** (centring origin, unit, centroid, rms radius: the sampling
  keys) from the streaming statistics (:func:`cloud_frame`);
* the **kernel widths** from the sample centres each tile fits
  (:func:`survey_tile`, :mod:`heatcurv.choice.survey`), joined in key order and
  decided once (:func:`merge_surveys`);
* the **medians** of the reliability flags after every tile is done
  (:func:`heatcurv.tiles.medians.apply_cloud_flags`, from the per-point inputs each tile returns).

Every other stage is local: a core point's values depend only on the points
within its reach (:func:`compute_tile` returns it; the task's certificate
checks it against the halo, :mod:`.tasks`).
"""

from __future__ import annotations

import numpy as np

from ..choice.choices import CloudFrame
from ..choice.plan import plan_fit
from ..choice.survey import GATE_LEVELS, fit_centres, join_keys, key_part, merge_fits, survey_part, tile_options
from ..choice.survey import merge_surveys as merge_centre_surveys
from ..estimator import estimate
from ..flags.outliers import find_outliers
from ..geometry.validation import bounding_box_frame
from ..operators.operator import HeatKernelOperator
from ..options import Options, resolve_options
from ..tuning import TUNING
from .context import SurveyContext

__all__ = [
    "survey_tile", "survey_halo", "survey_reach", "merge_surveys", "compute_tile", "cloud_frame", "describe",
    "key_halo", "key_tile", "plan_centres", "centre_reach", "gate_levels", "fit_tile_centres", "merge_rounds",
    "orients_outward", "orients_automatically", "RESULT_FIELDS", "RELIABILITY_FIELDS",
    "DEPTH", "HALO_MARGIN", "SURVEY_MARGIN", "ERRORS_HALO",
]

#: The certificate's dependency radius is DEPTH x what :func:`compute_tile` returns as ``support``;
#: that already is each point's whole reach (its fit's support plus the operator ball its
#: neighbours' normals and areas come from: ``info["reach"]`` of :func:`heatcurv.estimate`).
DEPTH = 1
#: A halo widened by the certificate is what the failing points need times this.
HALO_MARGIN = 1.1
#: The survey's first halo over its estimate (:func:`survey_halo`): a failed certificate surveys the tile
#: again, and on terrain the widest candidate's reach was 1.12-1.16 times the estimate (docs/tiles.md).
SURVEY_MARGIN = 1.25
#: The first halo of a run with standard errors, in the widest chosen ball (without them: 2, the fit's
#: ball and its neighbours'): a point's standard errors blend the nearest sample centres' (about 1.2
#: balls away at 8 refit pairs per point), whose windows hold the 16 nearest centres (2.5 balls) and
#: their refits at twice the kernel (1.4 balls) or their own values (2 balls).
ERRORS_HALO = 6.0

#: What :func:`compute_tile` returns for the core rows: name -> (columns, dtype).
RESULT_FIELDS = {
    "normals": (3, np.float64), "mean": (1, np.float64), "gaussian": (1, np.float64), "k1": (1, np.float64),
    "k2": (1, np.float64), "d1": (3, np.float64), "d2": (3, np.float64), "area": (1, np.float64),
    "reliable": (1, np.bool_), "outlier": (1, np.bool_), "border": (1, np.bool_), "spacing": (1, np.float64),
    "neighbours": (1, np.int64), "fit_radius": (1, np.float64),
    # the inputs of the two cloud-wide flags (heatcurv.flags.reliability), joined after the last tile
    "misfit_residual": (1, np.float64), "fit_width": (1, np.int64), "resolution_rho": (1, np.float64),
    "counted": (1, np.bool_),
    # the standard errors (NaN where the run does not compute them: se=False)
    "mean_se": (1, np.float64), "k1_se": (1, np.float64), "k2_se": (1, np.float64), "gaussian_se": (1, np.float64),
    "normal_se": (1, np.float64),
}
#: The fields of :data:`RESULT_FIELDS` that hold :class:`heatcurv.flags.reliability.ReliabilityInputs`, in its order
#: (``reliable`` holds its ``local`` flags until :func:`heatcurv.tiles.medians.apply_cloud_flags`).
RELIABILITY_FIELDS = ("reliable", "misfit_residual", "fit_width", "resolution_rho", "counted")


def cloud_frame(stats) -> CloudFrame:
    """The cloud's frame from the streaming statistics (:class:`.plan.CloudStats`)."""
    low, high = np.asarray(stats.low, dtype=float), np.asarray(stats.high, dtype=float)
    offset, unit = bounding_box_frame(low, high)
    centroid = (np.asarray(stats.centroid, dtype=float) - offset) / unit
    # distinct points, as in memory (0: statistics of a plan made before they were counted)
    n = int(getattr(stats, "distinct", 0) or stats.finite)
    return CloudFrame(offset, unit, n, centroid, float(stats.rms_radius) / unit)


def _estimate_options(options: dict) -> dict:
    """The options of :func:`heatcurv.estimate` that a survey takes (no viewpoint: its normals are unoriented)."""
    return {k: v for k, v in options.items() if k not in ("viewpoint", "orient", "progress")}


def operator_neighbours(options: dict) -> int:
    """The neighbours of the operator's balls (``k``) under a tiled run's estimator options."""
    return int(tile_options(_estimate_options(options)).neighbours)


def _core_ball(core_points: np.ndarray, options: dict) -> float:
    """The 90th percentile of the operator ball radius (``neighbours`` nearest) on a sample of a tile's core."""
    from scipy.spatial import cKDTree

    k0 = operator_neighbours(options)
    sample = core_points[:: max(1, len(core_points) // 2000)]
    # an unbalanced tree builds in about half the time; a k-nearest query's distances do not depend on it
    tree = cKDTree(core_points, balanced_tree=False, compact_nodes=False)
    radius = tree.query(sample, min(k0 + 1, len(core_points)))[0][:, -1]
    return float(np.quantile(radius, 0.9))


def survey_halo(core_points: np.ndarray, stats, options: dict, r0: float | None = None) -> float:
    """A first halo for a tile's survey: the widest candidate's ball, from the core's own density.

    The widest candidate holds ``k`` points, so its ball's radius is about
    ``sqrt(k / k_0)`` times the narrowest's (``k_0`` neighbours, measured on a
    sample of the core: ``r0``, :func:`_core_ball` unless given); the
    certificate widens it where that is not enough (surveying the tile again:
    hence :data:`SURVEY_MARGIN`, wider than :data:`HALO_MARGIN`).
    """
    from ..choice.scale import _ladder

    opts = tile_options(_estimate_options(options))
    k0 = int(opts.neighbours)
    widest = _ladder(k0, opts.scale_tuning.max_k, int(stats.finite))[-1].k
    r0 = _core_ball(core_points, options) if r0 is None else r0
    return r0 * (np.sqrt(widest / k0) + 1.0) * SURVEY_MARGIN


#: The keys' first halo, in operator balls of the core (:func:`key_halo`).
KEY_HALO = 1.5


def key_halo(core_points: np.ndarray, options: dict, r0: float | None = None) -> float:
    """A first halo for a tile's keys (round 1): :data:`KEY_HALO` operator balls, x :data:`HALO_MARGIN`."""
    r0 = _core_ball(core_points, options) if r0 is None else r0
    return KEY_HALO * r0 * HALO_MARGIN


def key_tile(points: np.ndarray, core: np.ndarray, stats, options: dict):
    """Round 1 of the survey on a tile (:func:`heatcurv.choice.survey.key_part`).

    Returns
    -------
    survey : heatcurv.choice.survey.KeySurvey
    reach : ndarray, shape (c,)
        Each core row's operator ball radius, input units (the certificate's).
    queried : tuple
        ``(prepared, neighbourhood)``: the ``k`` nearest it queried (:mod:`.neighbours`).
    """
    frame = cloud_frame(stats)
    survey, reach, queried = key_part(points, core, frame, **_estimate_options(options))
    return survey, reach * frame.unit, queried


def plan_centres(surveys: list, stats, options: dict):
    """The cloud's sample centres from every tile's keys (:func:`heatcurv.choice.survey.join_keys`)."""
    return join_keys(surveys, cloud_frame(stats), **_estimate_options(options))


def centre_reach(plan, places: np.ndarray, stats, options: dict, levels: int | None = None) -> np.ndarray:
    """A first guess of how far each centre's fits read, input units, shape (len(places),).

    The widest candidate it is fitted with holds ``k`` points: its ball is
    about ``sqrt(k / k_0)`` times the centre's operator ball (x
    :data:`CENTRE_MARGIN`); plus two of the cloud's largest operator balls,
    x :data:`HALO_MARGIN`. Round 2's
    certificate widens it where that is not enough.
    """
    frame = cloud_frame(stats)
    k0 = operator_neighbours(options)
    ball = plan.balls[places] * np.sqrt(plan.widths(places, levels) / k0) * CENTRE_MARGIN
    return (ball + 2.0 * plan.largest_ball) * HALO_MARGIN * frame.unit


#: The ball part of :func:`centre_reach`'s guess is widened by this: on a 50 000-point terrain in one tile
#: (``benchmarks/tiles.py``), the widest balls (7680 neighbours) of centres near the cloud's border, cut by
#: it, reached up to 1.5 x ``sqrt(k / k_0)`` operator balls (18 of 2000 centres past 1.3 x), and a guess
#: too small fits every centre of the tile again.
CENTRE_MARGIN = 1.5


def gate_levels(options: dict) -> int | None:
    """The candidates round 2 fits first: the noise gate's (:data:`heatcurv.choice.survey.GATE_LEVELS`) when the
    kernel is chosen (``scale="auto"``), else every one (a fixed ``scale`` needs its own width's fits)."""
    return GATE_LEVELS if tile_options(_estimate_options(options)).scale == "auto" else None


def fit_tile_centres(points: np.ndarray, stats, options: dict, plan, places: np.ndarray, levels: int | None = None,
                     knn=None):
    """Round 2 of the survey on a tile (:func:`heatcurv.choice.survey.fit_centres`); its ``reach`` in input units.

    ``knn``: the neighbourhoods round 1 stored (:func:`.neighbours.known_neighbours`).
    """
    frame = cloud_frame(stats)
    part = fit_centres(points, frame, plan, places, levels, knn, **_estimate_options(options))
    return part, part.reach * frame.unit, plan.positions[places] * frame.unit + frame.offset


def merge_rounds(parts: list, plan, stats, options: dict) -> SurveyContext:
    """:func:`merge_surveys` for the survey in two rounds: the choices, and a first halo for the tiles."""
    frame = cloud_frame(stats)
    choices = merge_fits(parts, plan, frame, **_estimate_options(options))
    return _first_halo(choices, [part.fits for part in parts], plan.largest_ball, frame, options)


def survey_tile(points: np.ndarray, core: np.ndarray, stats, options: dict, keep=None, bounded: bool = True,
                knn=None):
    """A tile's fits at its sample centres (:func:`heatcurv.choice.survey.survey_part`).

    Parameters
    ----------
    points : ndarray, shape (m, 3), float64
        The tile's core and halo points, input coordinates.
    core : ndarray, shape (m,), bool
        The tile's own rows.
    stats : CloudStats
        Count, bounding box, centroid and rms radius of the whole cloud.
    options : dict
        The keyword arguments of :func:`heatcurv.estimate`.
    keep : callable, optional
        ``keep(operator, outliers)``, called with the operator over ``points``
        and its outliers before the fits (a tiled run stores its
        neighbourhoods, areas and outliers for the tile phase, :mod:`.neighbours`).
    bounded : bool, optional
        Only the candidates below the key bound (:func:`heatcurv.choice.survey.key_bound`).
    knn : callable, optional
        The neighbourhoods known already (:func:`.neighbours.known_neighbours`).

    Returns
    -------
    heatcurv.choice.survey.CentreSurvey
    """
    frame, options = cloud_frame(stats), _estimate_options(options)
    op = HeatKernelOperator.from_points(points, tile_options(options), frame=frame, knn=knn)
    outliers = find_outliers(op.points, op.neighbourhood)
    if keep is not None:
        keep(op, outliers)
    return survey_part(points, core, frame, operator=op, outliers=outliers, bounded=bounded, **options)


def survey_reach(survey, stats) -> tuple[np.ndarray, np.ndarray]:
    """The survey's centres (input coordinates, shape (c, 3)) and how far their fits read (shape (c,))."""
    frame = cloud_frame(stats)
    return survey.positions * frame.unit + frame.offset, survey.reach * frame.unit


def merge_surveys(surveys: list, stats, options: dict) -> SurveyContext:
    """The choices every tile gets, and a first halo for the tiles.

    Returns
    -------
    SurveyContext
        ``choices``: :class:`heatcurv.choice.choices.CloudChoices`; ``halo``: twice the
        widest chosen ball plus the narrowest candidate's ball (the operator's),
        the largest the survey measured (at its centres; the operator's at every
        core point), input units: a first guess, which each tile's certificate
        checks point by point; ``support``: the widest chosen ball.
    """
    frame = cloud_frame(stats)
    choices = merge_centre_surveys(surveys, frame, **_estimate_options(options))
    largest = max((survey.largest_ball for survey in surveys), default=0.0)
    return _first_halo(choices, [survey.fits for survey in surveys], largest, frame, options)


def _first_halo(choices, fits: list, largest_ball: float, frame: CloudFrame, options: dict) -> SurveyContext:
    """:func:`merge_surveys`' result from the choices, every part's fits (``{label: CentreFits}`` each) and the
    largest operator ball of any core point (stages' units)."""
    opts = tile_options(_estimate_options(options))
    scale = choices.scale
    widest = int(scale.scale.k if scale.k_centre is None else scale.k_centre.max())
    base = int(opts.neighbours)

    def ball(k: int) -> float:
        """The largest ball of ``k`` neighbours, input units: of any point for the operator's ``k``, else of any
        surveyed centre (0 if none was fitted)."""
        h = [f.h for part in fits for label, f in part.items() if label.endswith(f"-{k}")]
        fitted = opts.alpha * float(max((x.max() for x in h if x.size), default=0.0))
        return (max(fitted, largest_ball) if k == base else fitted) * frame.unit

    chosen, operator = ball(widest), ball(base)
    balls = ERRORS_HALO if opts.se else 2.0
    return SurveyContext(choices, (balls * chosen + operator) * HALO_MARGIN, chosen)


def compute_tile(points: np.ndarray, core: np.ndarray, context: SurveyContext, options: dict, knn=None) -> dict:
    """Every result field of the core rows of a tile, and what the driver needs around them.

    Parameters
    ----------
    points : ndarray, shape (m, 3), float64
        The tile's core and halo points, input coordinates.
    core : ndarray, shape (m,), bool
        The tile's own rows.
    context : SurveyContext
        :func:`merge_surveys`' choices.
    options : dict
        The keyword arguments of :func:`heatcurv.estimate`.
    knn : callable, optional
        The neighbourhoods the survey queried (:func:`.neighbours.known_neighbours`).

    Returns
    -------
    dict of str to ndarray
        The :data:`RESULT_FIELDS` of the core rows (shapes (c,) or (c, 3);
        ``reliable`` without the cloud-wide flags, which
        :func:`heatcurv.tiles.medians.apply_cloud_flags` adds); ``support`` (c,): each core row's
        reach (its values depend on no point farther); ``halo_normals``
        (m - c, 3) of the halo rows; ``patch`` (m,) int: the connected pieces
        of the tile's surface, each of which the outward orientation signed on
        its own (one label 0 unless the orientation is ``outward``);
        ``winding`` dict or None: ``outward``, what the winding step needs
        (:mod:`.winding`; the estimate's ``info["winding"]``, None where the
        normals were oriented on anchors).
    """
    res = estimate(points, choices=context.choices, knn=knn, **options)
    fields = {name: getattr(res, name) for name in RESULT_FIELDS if hasattr(res, name)}
    for name in ("mean_se", "k1_se", "k2_se", "gaussian_se", "normal_se"):
        if fields[name] is None:
            fields[name] = np.full(len(points), np.nan)
    inputs = res.info["reliability"]
    fields["reliable"] = inputs.local
    fields["misfit_residual"] = np.full(len(points), np.nan) if inputs.residual is None else inputs.residual
    fields["fit_width"], fields["resolution_rho"], fields["counted"] = inputs.width, inputs.rho, inputs.counted
    out = {name: np.asarray(fields[name])[core] for name in RESULT_FIELDS}
    out["support"] = np.asarray(res.info["reach"])[core]
    out["halo_normals"] = res.normals[~core]
    outward = orients_outward(options, context.choices)
    out["patch"] = _patches(points, res.spacing, options) if outward else np.zeros(len(points), np.int64)
    out["winding"] = res.info.get("winding") if outward else None
    out["sheet_pairs"] = None
    if outward and res.info.get("sheet_pairs") is not None:
        out["sheet_pairs"] = _unsettled_sheets(res.info["sheet_pairs"], core, out, res.info["winding"])
    return out


def _unsettled_sheets(pairs, core: np.ndarray, out: dict, winding: dict) -> tuple[np.ndarray, np.ndarray]:
    """Settle the second-sheet pairs (:func:`heatcurv.flags.sheets.facing_pairs`) the tile can; the others.

    A pair of core points in one seam piece, one winding patch and one finer piece turns over together, so
    the tile's facing is the final one: where it faces away, the point gets area 0 and is not reliable
    (in ``out``, core rows). The pairs with an end in the halo or in another piece are returned, tile rows
    ``(p, q)`` with ``p`` in the core, for the driver (:mod:`.sheets`).
    """
    p, q, dot = pairs
    piece = np.column_stack([out["patch"], winding["patch"], winding["fine"]])
    settled = core[q] & np.all(piece[p] == piece[q], axis=1)
    mine = core[p]
    away = np.zeros(len(core), dtype=bool)
    away[p[mine & settled & (dot < -TUNING.sheet_aligned)]] = True
    at = np.flatnonzero(away[core])  # core-row positions
    out["area"][at] = 0.0
    out["reliable"][at] = False
    keep = mine & ~settled
    return p[keep], q[keep]


def resolved_options(options: dict) -> Options:
    """The :class:`heatcurv.options.Options` the tiles' estimator keywords resolve to (the viewpoint aside)."""
    estimator = {key: value for key, value in options.items() if key not in ("method", "viewpoint")}
    return resolve_options(options.get("method", "default"), **estimator)


def describe(context: SurveyContext, options: dict) -> dict:
    """The choices of :func:`merge_surveys` as plain numbers (for the output file's parameters and the report).

    ``options``: the tiles' estimator keywords (:func:`.driver.estimator_options`); the kernel is
    the label of the fit plan they and the survey's choice make (:func:`heatcurv.choice.plan.plan_fit`).
    """
    choices = context.choices
    frame, scale = choices.frame, choices.scale
    plan = plan_fit(resolved_options(options), scale)
    out = {
        "halo": float(context.halo), "support": float(context.support),
        "offset": frame.offset.tolist(), "unit": frame.unit, "points": frame.n_points,
        "centroid": (frame.centroid * frame.unit + frame.offset).tolist(), "rms_radius": frame.rms_radius * frame.unit,
        "kernel": plan.label, "sigma": scale.sigma * frame.unit, "relative_noise": scale.relative_noise,
    }
    policy = getattr(choices, "orientation", None)
    if policy is not None:  # what orient="auto" without a viewpoint chose (heatcurv.orient.auto.auto_policy)
        out["auto_orientation"] = policy.mode
        if policy.towards is not None:  # "up" along the cloud's own axis
            out["auto_towards"] = [float(c) for c in policy.towards]
    if scale.k_centre is not None:
        widths, counts = np.unique(scale.k_centre, return_counts=True)
        out["widths"] = {str(int(k)): int(c) for k, c in zip(widths, counts)}  # centres choosing each width
    return out


def orients_outward(options: dict, choices) -> bool:
    """Whether the options orient outward (the one policy that is not decided point by point).

    ``orient="auto"`` without a viewpoint follows the survey's choice (``choices.orientation``).
    """
    if orients_automatically(options):
        policy = getattr(choices, "orientation", None)
        return policy is None or policy.mode == "outward"
    return (options.get("orient") or "auto") == "outward"


def orients_automatically(options: dict) -> bool:
    """Whether the options leave the policy to ``orient="auto"`` (no viewpoint): the survey's sample decides."""
    return (options.get("orient") or "auto") == "auto" and options.get("viewpoint") is None


def _patches(points: np.ndarray, spacing: np.ndarray, options: dict) -> np.ndarray:
    """Connected components of the 10-nearest-neighbour graph (edges up to 4 x the spacing of either end).

    A few halo points of another object have a spacing as long as the way to this tile's points, so an
    edge is kept only within 4 spacings of both its ends (at least the tile's median spacing).
    """
    import scipy.sparse as sp
    from scipy.sparse import csgraph
    from scipy.spatial import cKDTree

    k = min(11, len(points))
    dist, idx = cKDTree(points).query(points, k=k, workers=options.get("workers", 1))
    spacing = np.asarray(spacing, dtype=float)
    keep = dist[:, 1:] <= 4.0 * np.maximum(np.minimum(spacing[:, None], spacing[idx[:, 1:]]), np.median(spacing))
    rows = np.repeat(np.arange(len(points)), k - 1).reshape(len(points), k - 1)[keep]
    graph = sp.csr_matrix((np.ones(rows.size), (rows, idx[:, 1:][keep])), shape=(len(points),) * 2)
    return csgraph.connected_components(graph, directed=False)[1].astype(np.int64)
