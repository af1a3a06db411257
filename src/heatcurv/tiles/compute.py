"""The ONE place a tiled run calls the numerical core: survey a tile, merge the surveys, compute a tile.

The driver (:mod:`.driver`) and the tasks (:mod:`.tasks`) call nothing else of
the core, so that making a tile's values equal the in-memory ones (global
spacing, noise level, kernel choice, sampling keys, medians and centring
passed into every tile: issue 13, bullet 3) changes the bodies below only.

First version: every tile runs :func:`heatcurv.estimate` on its core and halo
points with its own choices; the survey only measures how far a point's values
reach (the halo). See docs/tiles.md for what then differs from an in-memory run.
"""

from __future__ import annotations

import numpy as np

from ..estimator import estimate

__all__ = ["survey_tile", "merge_surveys", "compute_tile", "RESULT_FIELDS", "DEPTH", "HALO_MARGIN"]

#: Stages that read their neighbours' stage outputs: the fit uses neighbours' normals and areas (SCALE.md 4).
DEPTH = 2
#: The halo is the surveyed dependency radius times this (the certificate checks every point anyway).
HALO_MARGIN = 1.1

#: What :func:`compute_tile` returns for the core rows: name -> (columns, dtype).
RESULT_FIELDS = {
    "normals": (3, np.float64), "mean": (1, np.float64), "gaussian": (1, np.float64), "k1": (1, np.float64),
    "k2": (1, np.float64), "d1": (3, np.float64), "d2": (3, np.float64), "area": (1, np.float64),
    "reliable": (1, np.bool_), "outlier": (1, np.bool_), "border": (1, np.bool_), "spacing": (1, np.float64),
    "neighbours": (1, np.int64), "fit_radius": (1, np.float64),
}


def survey_tile(points: np.ndarray, core: np.ndarray, stats, options: dict) -> dict:
    """What one tile says about the global choices (first version: how far a point's values reach).

    Parameters
    ----------
    points : ndarray, shape (m, 3), float64
        A window of the tile's points, in the cloud's frame.
    core : ndarray, shape (m,), bool
        The rows whose values are not distorted by the window's edge.
    stats : CloudStats
        Count, bounding box and centroid of the whole cloud.
    options : dict
        The keyword arguments of :func:`heatcurv.estimate`.

    Returns
    -------
    dict
        ``support``: the largest support radius of a core row (its fit ball;
        the anchors' support radius where a wide kernel was carried),
        ``spacing``: the median spacing h, ``points``: rows surveyed.
    """
    res = estimate(points, **options)
    scale = res.info.get("scale")
    radius = np.asarray(res.fit_radius if res.fit_radius is not None else res.spacing * res.options.alpha)
    support = float(np.nanmax(radius[core])) if core.any() else float(np.nanmax(radius))
    if scale is not None and scale.anchors:
        support = max(support, float(scale.support_radius))
    return {"support": support, "spacing": float(np.median(res.spacing)), "points": int(len(points))}


def merge_surveys(surveys: list, stats, options: dict) -> dict:
    """The global choices every tile gets (first version: the halo width).

    Returns
    -------
    dict
        ``halo``: :data:`DEPTH` x the largest surveyed support radius x
        :data:`HALO_MARGIN`, length units; ``support``: that radius.
    """
    support = max(s["support"] for s in surveys)
    return {"halo": DEPTH * support * HALO_MARGIN, "support": support}


def compute_tile(points: np.ndarray, core: np.ndarray, context: dict, options: dict) -> dict:
    """Every result field of the core rows of a tile, and what the driver needs around them.

    Parameters
    ----------
    points : ndarray, shape (m, 3), float64
        The tile's core and halo points, in the cloud's frame.
    core : ndarray, shape (m,), bool
        The tile's own rows.
    context : dict
        :func:`merge_surveys`' global choices.
    options : dict
        The keyword arguments of :func:`heatcurv.estimate`.

    Returns
    -------
    dict of str to ndarray
        The :data:`RESULT_FIELDS` of the core rows (shapes (c,) or (c, 3));
        ``support`` (c,): each core row's support radius (its values depend on
        no point farther than :data:`DEPTH` x it); ``halo_normals`` (m - c, 3)
        of the halo rows; ``patch`` (m,) int: the connected pieces of the
        tile's surface, each of which the outward orientation signed on its own
        (one label 0 unless the orientation is ``outward``).
    """
    res = estimate(points, **options)
    out = {name: np.asarray(getattr(res, name))[core] for name in RESULT_FIELDS}
    radius = np.asarray(res.fit_radius)[core]
    scale = res.info.get("scale")
    # first version: an anchored (noisy) fit is carried from an anchor within about its own radius
    out["support"] = radius * (2.0 if scale is not None and scale.anchors else 1.0)
    out["halo_normals"] = res.normals[~core]
    out["patch"] = _patches(points, res.spacing, options) if _outward(options) else np.zeros(len(points), np.int64)
    return out


def _outward(options: dict) -> bool:
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
