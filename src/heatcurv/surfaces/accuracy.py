"""Error measures of an estimate against a sample's exact values, as the paper and docs/testing.md define them.

Used by the demo, the benchmarks and the tests, so every number we quote is
computed the same way:

* eq 5.1 of the paper: ``mean_i ||k_i| - |k*_i||`` (absolute, unsigned);
* the signed relative L1 error ``mean|k - k*| / mean|k*|``;
* eq 4.1: the mean angle between estimated and exact principal directions
  (as lines: the sign of a direction is arbitrary), from ``atan2`` so that
  angles down to rounding (1e-14 deg) are resolved;
* the relative error of the total area.

Signs are compared after aligning the exact normals with the estimated ones
(one global flip per sample: graphs have upward exact normals, heatcurv
orients open patches by its own rule).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "aligned_exact",
    "relative_l1",
    "paper_error",
    "direction_error_deg",
    "default_margin",
    "neighbour_margin",
    "compare",
]


def aligned_exact(sample, result) -> dict:
    """Exact values of ``sample`` expressed for the orientation of ``result.normals``.

    If the estimated normals point against the exact ones (by majority), the
    exact signed curvatures change sign, ``k1 <-> -k2`` and ``d1 <-> d2``.

    Parameters
    ----------
    sample : heatcurv.surfaces.SurfaceSample
    result : heatcurv.CurvatureResult

    Returns
    -------
    dict
        ``normals`` (n, 3), ``mean``, ``k1``, ``k2``, ``gaussian`` (n,), ``d1``, ``d2`` (n, 3), ``flipped`` (bool).
    """
    flip = bool(np.mean(np.sign(np.einsum("ij,ij->i", result.normals, sample.normals))) < 0)
    s = -1.0 if flip else 1.0
    return {
        "normals": s * sample.normals,
        "mean": s * sample.mean,
        "k1": -sample.k2 if flip else sample.k1,
        "k2": -sample.k1 if flip else sample.k2,
        "d1": sample.d2 if flip else sample.d1,
        "d2": sample.d1 if flip else sample.d2,
        "gaussian": sample.gaussian,
        "flipped": flip,
    }


def relative_l1(estimate: np.ndarray, exact: np.ndarray) -> float:
    """``mean|estimate - exact| / mean|exact|``; NaN where the exact field is zero."""
    scale = float(np.mean(np.abs(exact)))
    return float(np.mean(np.abs(estimate - exact)) / scale) if scale > 0 else float("nan")


def paper_error(estimate: np.ndarray, exact: np.ndarray) -> float:
    """Eq 5.1: ``mean ||k| - |k*||`` (absolute; multiply by 100 for the paper's "%")."""
    return float(np.mean(np.abs(np.abs(estimate) - np.abs(exact))))


def direction_error_deg(estimate: np.ndarray, exact: np.ndarray) -> float:
    """Eq 4.1: mean angle between direction lines, degrees; shapes (n, 3).

    ``atan2(|a x b|, |a . b|)``: exact to rounding at small angles, where
    ``arccos`` of a dot product near 1 cannot resolve less than ~1e-6 deg.
    """
    if not estimate.size:
        return float("nan")
    sine = np.linalg.norm(np.cross(estimate, exact), axis=1)
    cosine = np.abs(np.einsum("ij,ij->i", estimate, exact))
    return float(np.degrees(np.mean(np.arctan2(sine, cosine))))


def default_margin(result) -> float:
    """The border margin :func:`compare` uses when it is given none.

    The radius of the widest neighbourhood the estimator looked at, so that
    "interior" points are those no neighbourhood of which reaches the border:

    * a result that states its own neighbourhood radius as ``support_radius``
      uses it: the ``support_radius`` of the tests' quadric baseline (``tests/support/baseline.py``), the
      largest k-NN radius;
    * otherwise the result is taken for a :class:`heatcurv.CurvatureResult`
      (anything with ``options.alpha`` and ``spacing``): the largest ball
      radius ``alpha * max(h)``.

    Parameters
    ----------
    result : heatcurv.CurvatureResult or the tests' QuadricResult

    Returns
    -------
    float
    """
    support = getattr(result, "support_radius", None)
    if support is not None:
        return float(support)
    return result.options.alpha * float(np.max(result.spacing))


def neighbour_margin(points: np.ndarray, k: int = 40) -> float:
    """A border margin fixed by the sampling alone: the 99th percentile of the ``k``-th neighbour distance.

    Unlike :func:`default_margin` it does not depend on the estimate, so the
    points judged as interior (and the border band judged separately) stay
    the same when the estimator widens or narrows its balls.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    k : int, optional
        Neighbours, self excluded (40: the quadric baseline's neighbourhood).

    Returns
    -------
    float
    """
    from scipy.spatial import cKDTree

    d, _ = cKDTree(points).query(points, k + 1)
    return float(np.percentile(d[:, -1], 99))


def compare(sample, result, margin: float | None = None) -> dict:
    """All error measures of ``result`` against ``sample``'s exact values.

    Parameters
    ----------
    sample : heatcurv.surfaces.SurfaceSample
    result : heatcurv.CurvatureResult or the tests' QuadricResult
        Computed on ``sample.points``, same order.
    margin : float, optional
        Interior points are farther than this from the border of open
        surfaces; default :func:`default_margin` (the largest ball radius
        ``alpha * max(h)`` of a heatcurv result, the largest k-NN radius of a
        quadric fit).

    Returns
    -------
    dict
        ``interior`` (mask), per field ``rel_<f>`` and ``eq51_<f>`` for f in
        mean, k1, k2, gaussian (on interior points), ``rel_mean_all``
        (every point), ``d1_deg`` (interior, non-umbilic), ``normal_deg``,
        ``orientation`` (fraction of normals on the aligned exact side),
        ``area`` (relative error of the total; biased by the border on open
        surfaces), ``reliable`` (fraction); on the border band (the points
        within ``margin`` of the border; NaN on closed surfaces):
        ``border_rel_<f>`` for f in mean, k1, k2, ``border_d1_deg`` and
        ``border_normal_deg``.
    """
    ex = aligned_exact(sample, result)
    if margin is None:
        margin = default_margin(result)
    inner = sample.interior(margin)
    out = {"interior": inner}
    for name in ("mean", "k1", "k2", "gaussian"):
        est, exact = getattr(result, name)[inner], ex[name][inner]
        out[f"rel_{name}"] = relative_l1(est, exact)
        out[f"eq51_{name}"] = paper_error(est, exact)
    out["rel_mean_all"] = relative_l1(result.mean, ex["mean"])
    dirs = inner & ~sample.umbilic
    out["d1_deg"] = direction_error_deg(result.d1[dirs], ex["d1"][dirs])
    out["normal_deg"] = direction_error_deg(result.normals[inner], ex["normals"][inner])
    out["orientation"] = float(np.mean(np.einsum("ij,ij->i", result.normals, ex["normals"]) > 0))
    out["area"] = float(result.area.sum() / sample.total_area - 1.0)
    out["reliable"] = float(np.mean(result.reliable))
    band = ~inner
    nan = float("nan")
    for name in ("mean", "k1", "k2"):
        out[f"border_rel_{name}"] = relative_l1(getattr(result, name)[band], ex[name][band]) if band.any() else nan
    dirs = band & ~sample.umbilic
    out["border_d1_deg"] = direction_error_deg(result.d1[dirs], ex["d1"][dirs])
    out["border_normal_deg"] = direction_error_deg(result.normals[band], ex["normals"][band])
    return out
