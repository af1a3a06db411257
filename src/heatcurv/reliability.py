"""The reliability flags that compare a point with the whole cloud: misfits and the resolution check.

Most of ``result.reliable`` is a point's own business (its ball, its fit, its
orientation: :func:`heatcurv.estimate`). Two flags compare it with medians over
every point of the cloud, so a tiled run (:mod:`heatcurv.tiles`) can only set
them once all tiles are done:

* a **misfit** is a point whose fit residual (in units of its spacing) exceeds
  :data:`MISFIT_FACTOR` times the median of the points fitted at the same
  kernel width: one smooth surface does not explain its ball;
* the **resolution** of the cloud is the median point's sampling spacing in
  radii of curvature; above :data:`RESOLUTION_LIMIT` the balls wrap around the
  surface and no value is reliable.

:class:`ReliabilityInputs` holds what each point contributes; the functions
below turn a whole cloud's inputs into the flags.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .errors import HeatcurvWarning

__all__ = [
    "MISFIT_FACTOR", "MISFIT_FLOOR", "RESOLUTION_LIMIT", "ReliabilityInputs", "cloud_flags", "misfit_baselines",
    "misfits", "resolution",
]

#: A point whose chord-fit residual (in units of its spacing) exceeds this multiple of the
#: cloud's median is not explained by one smooth surface at the kernel's scale: a sharp edge
#: inside the ball, vegetation, a veil. Measured (residual / median): noisy tori at most 1.4,
#: a CAD part's faces 0.1 and the band of a ball's width along its edges 3-450, a LiDAR tile's
#: ground 0.8-7 and its tree crowns 20-36.
MISFIT_FACTOR = 10.0
#: Floor of the median residual (in spacings) a clean cloud's misfits are measured against.
MISFIT_FLOOR = 1e-3
#: A cloud whose median point has a sampling spacing ``s = R sqrt(pi / count)`` (its ball's radius
#: ``R`` holding ``count`` neighbours) more than this many radii of curvature ``1 / max(|k1|, |k2|)``
#: (fewer than about 12 points around an osculating circle) does not resolve its surface: its
#: balls wrap around it. Measured (median, random samples): tori (r 0.6, R 1.4) of 150, 200 and
#: 300 points 0.63, 0.62 and 0.53, with 45 and 53 inward normals among the "reliable" points of
#: the first two and mean errors of 5.5-24 % of the largest curvature; 600 points 0.38 (2.9 %);
#: spheres of 150 points 0.29 (0.4 %); ellipsoids (1, 0.6, 0.3) of 150-600 points 0.24-0.48;
#: noisy clouds of 3000-10 000 points 0.04-0.18.
RESOLUTION_LIMIT = 0.5


@dataclass(frozen=True)
class ReliabilityInputs:
    """What each point contributes to the cloud-wide flags, shape (n,) each.

    Attributes
    ----------
    local : ndarray of bool
        Every reliability flag that is the point's own (ball, fit, area,
        border, orientation, outlier).
    residual : ndarray or None
        Fit residual over the point's spacing ``h`` (None: the paper's fit,
        which has no residual and no misfits).
    width : ndarray of int
        Kernel width (neighbours) the point was fitted at (0: one width).
    rho : ndarray
        Sampling spacing in radii of curvature (nan where undefined).
    counted : ndarray of bool
        Points the medians are taken over: distinct surface points (not
        outliers; one row per set of exact duplicates).
    """

    local: np.ndarray
    residual: np.ndarray | None
    width: np.ndarray
    rho: np.ndarray
    counted: np.ndarray

    def take(self, rows: np.ndarray) -> ReliabilityInputs:
        """The inputs of ``rows`` only (e.g. a tile's core)."""
        return ReliabilityInputs(
            self.local[rows], None if self.residual is None else self.residual[rows], self.width[rows],
            self.rho[rows], self.counted[rows],
        )


def misfit_baselines(residual: np.ndarray, width: np.ndarray, counted: np.ndarray) -> dict:
    """The median residual of the counted points of each kernel width, at least :data:`MISFIT_FLOOR`.

    Against one median per width (a wider kernel's residual holds more of the
    surface's shape: a low-poly bone with regions at 60 and 120 neighbours had
    18 % of its points "misfits" against one median, 2 % with one per width).

    Returns
    -------
    dict
        ``{width: baseline}`` for every width present.
    """
    baselines = {}
    for k in np.unique(width):
        surface = residual[(width == k) & counted]
        baselines[int(k)] = max(float(np.median(surface)) if surface.size else 0.0, MISFIT_FLOOR)
    return baselines


def misfits(residual: np.ndarray | None, width: np.ndarray, baselines: dict) -> np.ndarray:
    """Points whose residual exceeds :data:`MISFIT_FACTOR` times their width's baseline, shape (n,), bool."""
    if residual is None:
        return np.zeros(width.shape[0], dtype=bool)
    widths = np.array(sorted(baselines), dtype=np.int64)
    limit = MISFIT_FACTOR * np.array([baselines[k] for k in widths.tolist()])
    return residual > limit[np.searchsorted(widths, width)]


def resolution(rho: np.ndarray, counted: np.ndarray) -> float:
    """The median counted point's spacing in radii of curvature (:data:`RESOLUTION_LIMIT`); 0 if none counts."""
    values = rho[counted & np.isfinite(rho)]
    return float(np.median(values)) if values.size else 0.0


def cloud_flags(inputs: ReliabilityInputs, baselines: dict | None = None, resolution_value: float | None = None,
                stacklevel: int = 2) -> tuple[np.ndarray, float]:
    """``reliable`` for every point, from the whole cloud's inputs.

    Parameters
    ----------
    inputs : ReliabilityInputs
        Every point of the cloud.
    baselines, resolution_value : optional
        The medians, if already taken (a tiled run takes them over all its
        tiles); default: from ``inputs``.
    stacklevel : int, optional
        Of the warning.

    Returns
    -------
    reliable : ndarray of bool, shape (n,)
    resolution : float

    Warns
    -----
    HeatcurvWarning
        When the cloud is too coarse for its curvature (every value unreliable).
    """
    if inputs.residual is not None and baselines is None:
        baselines = misfit_baselines(inputs.residual, inputs.width, inputs.counted)
    reliable = inputs.local & ~misfits(inputs.residual, inputs.width, baselines or {})
    rho = resolution(inputs.rho, inputs.counted) if resolution_value is None else resolution_value
    if rho > RESOLUTION_LIMIT:
        warnings.warn(
            f"the cloud is too coarse for its curvature: a median point's spacing is {rho:.2g} radii of "
            f"curvature (at most {RESOLUTION_LIMIT:g}: about 12 points around a curve), so its neighbourhoods "
            "wrap around the surface; every value is marked unreliable. Sample it more densely.",
            HeatcurvWarning, stacklevel=stacklevel + 1,
        )
        reliable = np.zeros_like(reliable)
    return reliable, rho
