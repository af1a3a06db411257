"""Sharp-feature detection from the heat-kernel mean curvature (the paper's application, section 4).

Across a crease of turning angle ``phi`` (interior angle ``180 - phi`` degrees)
the heat-kernel mean curvature does not diverge: the kernel spreads the
crease over a width of about ``h``. At the crease line the mean-curvature
normal of eq 2.10 evaluates in closed form (two half-planes each tilted by
``beta = phi/2``):

    kappa_M = 1/2 K . n = 2 sin(beta) / (sqrt(pi) h)       (t = h^2 / 4)

so ``2 arcsin(sqrt(pi) |kappa_M| h / 2)`` recovers the turning angle from the
mean curvature and the spacing. That is the continuum limit; on a grid whose
step equals ``h`` (eq 2.6) the sum over the lattice replaces
``int |s| exp(-s^2/h^2) ds = h^2`` by ``2 sum_k k exp(-k^2) h^2 = 0.81 h^2``, and
the measured score at the crease of the paper's folded square (961 points) is
0.63-0.86 times the true turning angle (1 to 120 degrees). We use it as the feature score, in degrees:
it is independent of the cloud's scale and density, it reads as "how much
the surface turns within about two spacings", and on a smooth surface of
radius ``R`` it is about ``sqrt(pi) h / R`` radians, small when the sampling
resolves the surface.

The automatic threshold is Otsu's between-class variance split of the scores
(features and smooth surface form two populations), but never below
``min_angle`` (10 degrees by default) nor below ``background`` (3) times the
median score: a feature turns markedly more than the surface around it, so a
smooth or flat cloud, or a coarsely sampled curved one whose every point
turns by a similar angle within the kernel, reports no features.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import HeatcurvError
from .estimator import estimate
from .options import Range, range_problem
from .results import CurvatureResult

__all__ = ["FEATURE_RANGES", "FeatureResult", "feature_score", "otsu_threshold", "sharp_features"]

#: The documented ranges of :func:`sharp_features`'s numbers.
FEATURE_RANGES: dict[str, Range] = {
    "threshold": Range(0.0, 180.0, False, "a turning angle of the surface, in degrees"),
    "min_angle": Range(0.0, 180.0, False, "a turning angle of the surface, in degrees"),
    "background": Range(
        0.0, 1000.0, False, "a multiple of the median score (3 by default); 0 leaves only Otsu's split and min_angle",
    ),
}


@dataclass(frozen=True)
class FeatureResult:
    """Sharp features of a point cloud.

    Attributes
    ----------
    score : ndarray, shape (n,)
        Estimated turning angle of the surface around each point, degrees.
    mask : ndarray, shape (n,), bool
        ``score > threshold``: points on or next to a sharp feature.
    threshold : float
        The threshold used, degrees.
    """

    score: np.ndarray
    mask: np.ndarray
    threshold: float


def feature_score(mean: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """Turning angle in degrees, ``2 arcsin(sqrt(pi) |kappa_M| h / 2)``.

    Parameters
    ----------
    mean : ndarray, shape (n,)
        Mean curvature (eq 2.11 or 2.12).
    spacing : ndarray, shape (n,)
        Spacing ``h`` the mean curvature was computed with (``t = h^2 / 4``).

    Returns
    -------
    ndarray, shape (n,)
        Degrees in [0, 180]; exact at the crease line of a fold in the
        continuum limit.
    """
    s = np.sqrt(np.pi) * np.abs(np.asarray(mean)) * np.asarray(spacing) / 2.0
    return np.degrees(2.0 * np.arcsin(np.clip(s, 0.0, 1.0)))


def otsu_threshold(values: np.ndarray, bins: int = 256) -> float:
    """Otsu's threshold: the split maximising the between-class variance.

    Parameters
    ----------
    values : ndarray, shape (n,)
    bins : int, optional
        Histogram bins.

    Returns
    -------
    float
        A value between the two populations (the histogram edge at the best split).
    """
    values = np.asarray(values, dtype=np.float64)
    lo, hi = float(values.min()), float(values.max())
    if hi <= lo:
        return hi
    hist, edges = np.histogram(values, bins=bins, range=(lo, hi))
    centers = 0.5 * (edges[:-1] + edges[1:])
    w0 = np.cumsum(hist)[:-1].astype(np.float64)
    w1 = hist.sum() - w0
    s0 = np.cumsum(hist * centers)[:-1]
    mu0 = s0 / np.maximum(w0, 1)
    mu1 = (np.sum(hist * centers) - s0) / np.maximum(w1, 1)
    between = w0 * w1 * (mu0 - mu1) ** 2
    # Between well-separated populations the criterion is flat over the gap (moving the
    # split past a few stragglers barely changes it); take the middle of the near-optimal
    # splits rather than the first, so the threshold sits in the gap.
    near = np.flatnonzero(between >= 0.99 * between.max())
    return float(edges[1 + (near[0] + near[-1]) // 2])


def sharp_features(
    points_or_result, threshold: float | None = None, min_angle: float = 10.0, background: float = 3.0, **options
) -> FeatureResult:
    """Detect sharp features (creases, corners) from the mean curvature.

    Parameters
    ----------
    points_or_result : array_like, shape (n, 3), or CurvatureResult
        A point cloud (then :func:`heatcurv.estimate` runs with ``options``)
        or a result already computed.
    threshold : float, optional
        Turning angle in degrees above which a point is a feature. Default:
        automatic (Otsu's split of the scores, at least ``min_angle`` and at
        least ``background`` times the median score).
    min_angle : float, optional
        Floor of the automatic threshold, degrees.
    background : float, optional
        The automatic threshold is at least this multiple of the median score.
    **options
        Passed to :func:`heatcurv.estimate`.

    Returns
    -------
    FeatureResult

    Examples
    --------
    >>> import heatcurv
    >>> fold = heatcurv.surfaces.FoldedSquare(interior_angle=90).sample(961, "grid")
    >>> feat = heatcurv.sharp_features(fold.points)
    >>> bool(feat.mask.any())
    True
    """
    for name, value in (("min_angle", min_angle), ("background", background)):
        problem = range_problem(name, value, FEATURE_RANGES[name])
        if problem is not None:
            raise HeatcurvError(problem)
    if isinstance(points_or_result, CurvatureResult):
        if options:
            raise HeatcurvError("options are for estimate(); they cannot change a result already computed")
        res = points_or_result
    else:
        res = estimate(points_or_result, **options)
    # the heat-kernel mean curvature 1/2 K.n (eq 2.12), whatever estimator filled res.mean:
    # the closed form above holds for it
    kappa = 0.5 * np.einsum("ij,ij->i", res.mean_curvature_normal, res.normals)
    score = feature_score(kappa, res.spacing)
    if threshold is None:
        thr = max(otsu_threshold(score), float(min_angle), float(background) * float(np.median(score)))
    else:
        problem = range_problem("threshold", threshold, FEATURE_RANGES["threshold"])
        if problem is not None:
            raise HeatcurvError(problem)
        thr = float(threshold)
    return FeatureResult(score=score, mask=score > thr, threshold=thr)
