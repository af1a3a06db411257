"""The ONE place a tiled run calls the numerical core: survey a tile, merge the surveys, compute a tile.

The driver (:mod:`.driver`) and the tasks (:mod:`.tasks`) call nothing else of
the core. A tile computes as the whole cloud would (issue 13, bullet 3)
because every choice that is not a point's own is made once
(:mod:`heatcurv.choices`):

* the **frame** (centring origin, unit, centroid, rms radius: the sampling
  keys) from the streaming statistics (:func:`cloud_frame`);
* the **kernel widths** from the sample centres each tile fits
  (:func:`survey_tile`, :mod:`heatcurv.survey`), joined in key order and
  decided once (:func:`merge_surveys`);
* the **medians** of the reliability flags after every tile is done
  (:func:`finish_reliability`, from the per-point inputs each tile returns).

Every other stage is local: a core point's values depend only on the points
within its reach (:func:`compute_tile` returns it; the task's certificate
checks it against the halo, :mod:`.tasks`).
"""

from __future__ import annotations

import numpy as np

from ..choices import CloudFrame
from ..estimator import estimate
from ..reliability import ReliabilityInputs, cloud_flags
from ..survey import merge_surveys as merge_centre_surveys
from ..survey import survey_part, tile_options
from ..validation import bounding_box_frame

__all__ = [
    "survey_tile", "survey_halo", "survey_reach", "merge_surveys", "compute_tile", "cloud_frame", "describe",
    "orients_outward", "finish_reliability", "RESULT_FIELDS", "RELIABILITY_FIELDS", "DEPTH", "HALO_MARGIN",
]

#: The certificate's dependency radius is DEPTH x what :func:`compute_tile` returns as ``support``;
#: that already is each point's whole reach (its fit's support plus the operator ball its
#: neighbours' normals and areas come from: ``info["reach"]`` of :func:`heatcurv.estimate`).
DEPTH = 1
#: A halo widened by the certificate is what the failing points need times this.
HALO_MARGIN = 1.1

#: What :func:`compute_tile` returns for the core rows: name -> (columns, dtype).
RESULT_FIELDS = {
    "normals": (3, np.float64), "mean": (1, np.float64), "gaussian": (1, np.float64), "k1": (1, np.float64),
    "k2": (1, np.float64), "d1": (3, np.float64), "d2": (3, np.float64), "area": (1, np.float64),
    "reliable": (1, np.bool_), "outlier": (1, np.bool_), "border": (1, np.bool_), "spacing": (1, np.float64),
    "neighbours": (1, np.int64), "fit_radius": (1, np.float64),
    # the inputs of the two cloud-wide flags (heatcurv.reliability), joined after the last tile
    "misfit_residual": (1, np.float64), "fit_width": (1, np.int64), "resolution_rho": (1, np.float64),
    "counted": (1, np.bool_),
}
#: The fields of :data:`RESULT_FIELDS` that hold :class:`heatcurv.reliability.ReliabilityInputs`, in its order
#: (``reliable`` holds its ``local`` flags until :func:`finish_reliability`).
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


def survey_halo(core_points: np.ndarray, stats, options: dict) -> float:
    """A first halo for a tile's survey: the widest candidate's ball, from the core's own density.

    The widest candidate holds ``k`` points, so its ball's radius is about
    ``sqrt(k / k_0)`` times the narrowest's (``k_0`` neighbours, measured on a
    sample of the core); the certificate widens it where that is not enough.
    """
    from scipy.spatial import cKDTree

    from ..scale import _ladder

    opts = tile_options(_estimate_options(options))
    k0 = int(opts.neighbours)
    widest = _ladder(k0, opts.scale_tuning.max_k, int(stats.finite))[-1].k
    sample = core_points[:: max(1, len(core_points) // 2000)]
    radius = cKDTree(core_points).query(sample, min(k0 + 1, len(core_points)))[0][:, -1]
    r0 = float(np.quantile(radius, 0.9))
    return r0 * (np.sqrt(widest / k0) + 1.0) * HALO_MARGIN


def survey_tile(points: np.ndarray, core: np.ndarray, stats, options: dict):
    """A tile's fits at its sample centres (:func:`heatcurv.survey.survey_part`).

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

    Returns
    -------
    heatcurv.survey.CentreSurvey
    """
    return survey_part(points, core, cloud_frame(stats), **_estimate_options(options))


def survey_reach(survey, stats) -> tuple[np.ndarray, np.ndarray]:
    """The survey's centres (input coordinates, shape (c, 3)) and how far their fits read (shape (c,))."""
    frame = cloud_frame(stats)
    return survey.positions * frame.unit + frame.offset, survey.reach * frame.unit


def merge_surveys(surveys: list, stats, options: dict) -> dict:
    """The choices every tile gets, and a first halo for the tiles.

    Returns
    -------
    dict
        ``choices``: :class:`heatcurv.choices.CloudChoices`; ``halo``: twice the
        widest chosen ball plus the narrowest candidate's ball (the operator's),
        the largest the survey measured, input units: a first guess, which each
        tile's certificate checks point by point; ``support``: the widest chosen ball.
    """
    frame = cloud_frame(stats)
    opts = tile_options(_estimate_options(options))
    choices = merge_centre_surveys(surveys, frame, **_estimate_options(options))
    scale = choices.scale
    widest = int(scale.scale.k if scale.k_centre is None else scale.k_centre.max())

    def ball(k: int) -> float:
        """The largest ball of ``k`` neighbours at any surveyed centre, input units (0 if none was fitted)."""
        h = [fits.h for s in surveys for label, fits in s.fits.items() if label.endswith(f"-{k}")]
        return opts.alpha * float(max((x.max() for x in h if x.size), default=0.0)) * frame.unit

    chosen, operator = ball(widest), ball(int(opts.neighbours))
    return {"choices": choices, "halo": (2.0 * chosen + operator) * HALO_MARGIN, "support": chosen}


def compute_tile(points: np.ndarray, core: np.ndarray, context: dict, options: dict) -> dict:
    """Every result field of the core rows of a tile, and what the driver needs around them.

    Parameters
    ----------
    points : ndarray, shape (m, 3), float64
        The tile's core and halo points, input coordinates.
    core : ndarray, shape (m,), bool
        The tile's own rows.
    context : dict
        :func:`merge_surveys`' choices.
    options : dict
        The keyword arguments of :func:`heatcurv.estimate`.

    Returns
    -------
    dict of str to ndarray
        The :data:`RESULT_FIELDS` of the core rows (shapes (c,) or (c, 3);
        ``reliable`` without the cloud-wide flags, which
        :func:`finish_reliability` adds); ``support`` (c,): each core row's
        reach (its values depend on no point farther); ``halo_normals``
        (m - c, 3) of the halo rows; ``patch`` (m,) int: the connected pieces
        of the tile's surface, each of which the outward orientation signed on
        its own (one label 0 unless the orientation is ``outward``).
    """
    res = estimate(points, choices=context["choices"], **options)
    fields = {name: getattr(res, name) for name in RESULT_FIELDS if hasattr(res, name)}
    inputs = res.info["reliability"]
    fields["reliable"] = inputs.local
    fields["misfit_residual"] = np.full(len(points), np.nan) if inputs.residual is None else inputs.residual
    fields["fit_width"], fields["resolution_rho"], fields["counted"] = inputs.width, inputs.rho, inputs.counted
    out = {name: np.asarray(fields[name])[core] for name in RESULT_FIELDS}
    out["support"] = np.asarray(res.info["reach"])[core]
    out["halo_normals"] = res.normals[~core]
    outward = orients_outward(options)
    out["patch"] = _patches(points, res.spacing, options) if outward else np.zeros(len(points), np.int64)
    return out


def finish_reliability(columns, medians=None) -> tuple[np.ndarray, float]:
    """``reliable`` of rows from their :data:`RELIABILITY_FIELDS` columns and the cloud's medians.

    Parameters
    ----------
    columns : dict
        The :data:`RELIABILITY_FIELDS` arrays of some rows.
    medians : tuple, optional
        ``(baselines, resolution)`` over the whole cloud
        (:func:`heatcurv.reliability.misfit_baselines`,
        :func:`heatcurv.reliability.resolution`); default: from these rows.

    Returns
    -------
    reliable : ndarray of bool
    resolution : float
    """
    residual = np.asarray(columns["misfit_residual"], dtype=float)
    inputs = ReliabilityInputs(
        np.asarray(columns["reliable"], dtype=bool), None if np.isnan(residual).all() else residual,
        np.asarray(columns["fit_width"], dtype=np.int64), np.asarray(columns["resolution_rho"], dtype=float),
        np.asarray(columns["counted"], dtype=bool),
    )
    baselines, rho = (None, None) if medians is None else medians
    return cloud_flags(inputs, baselines, rho, stacklevel=3)


def describe(context: dict) -> dict:
    """The choices of :func:`merge_surveys` as plain numbers (for the output file's parameters and the report)."""
    choices = context["choices"]
    frame, scale = choices.frame, choices.scale
    out = {
        "halo": float(context["halo"]), "support": float(context["support"]),
        "offset": frame.offset.tolist(), "unit": frame.unit, "points": frame.n_points,
        "centroid": (frame.centroid * frame.unit + frame.offset).tolist(), "rms_radius": frame.rms_radius * frame.unit,
        "kernel": scale.scale.label, "sigma": scale.sigma * frame.unit, "relative_noise": scale.relative_noise,
    }
    if scale.k_centre is not None:
        widths, counts = np.unique(scale.k_centre, return_counts=True)
        out["widths"] = {str(int(k)): int(c) for k, c in zip(widths, counts)}  # centres choosing each width
    return out


def orients_outward(options: dict) -> bool:
    """Whether the options orient outward (the one policy that is not decided point by point)."""
    orient = options.get("orient") or "auto"
    return orient == "outward" or (orient == "auto" and options.get("viewpoint") is None)


def _patches(points: np.ndarray, spacing: np.ndarray, options: dict) -> np.ndarray:
    """Connected components of the 10-nearest-neighbour graph (edges up to 4 x the spacing)."""
    import scipy.sparse as sp
    from scipy.sparse import csgraph
    from scipy.spatial import cKDTree

    k = min(11, len(points))
    dist, idx = cKDTree(points).query(points, k=k, workers=options.get("workers", 1))
    keep = dist[:, 1:] <= 4.0 * np.maximum(spacing, np.median(spacing))[:, None]
    rows = np.repeat(np.arange(len(points)), k - 1).reshape(len(points), k - 1)[keep]
    graph = sp.csr_matrix((np.ones(rows.size), (rows, idx[:, 1:][keep])), shape=(len(points),) * 2)
    return csgraph.connected_components(graph, directed=False)[1].astype(np.int64)
