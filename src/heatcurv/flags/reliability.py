"""The reliability flags that compare a point with the whole cloud: misfits and the resolution check.

Most of ``result.reliable`` is a point's own business (its ball, its fit, its
orientation: :func:`heatcurv.estimate`). Two flags compare it with medians over
every point of the cloud, so a tiled run (:mod:`heatcurv.tiles`) can only set
them once all tiles are done:

* a **misfit** is a point whose fit residual (in units of its spacing) exceeds
  ``TUNING.misfit_factor`` times the median of the points fitted at the same
  kernel width (``TUNING.noise_misfit_factor`` where the residual of the cloud's
  smooth parts is noise, about the same at every point:
  :func:`heatcurv.choice.plan.noisy_residuals`): one smooth surface does not
  explain its ball;
* the **resolution** of the cloud is the median point's sampling spacing in
  radii of curvature; above ``TUNING.resolution_limit`` the balls wrap around the
  surface and no value is reliable.

:class:`ReliabilityInputs` holds what each point contributes; the functions
below turn a whole cloud's inputs into the flags.

One of a point's own flags is also decided here: the **precision** of its
coordinates. Coordinates stored in float32, or rounded to a grid (a LAS file's
scale), are each off by up to half a step of that grid;
:func:`coordinate_rounding` finds the step and :func:`imprecise` flags the
points whose curvature that rounding can move by more than
``TUNING.precision_tolerance`` of its size. So is another limit of the data
rather than of the point: noise too thick for the fit's ball
(:func:`flattened`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import HeatcurvError, HeatcurvWarning
from ..tuning import TUNING

__all__ = [
    "PrecisionReport", "ReliabilityInputs", "cloud_flags", "coordinate_rounding", "flattened", "imprecise",
    "misfit_baselines",
    "misfits", "precision_step", "resolution", "rounding_height_variance", "rounding_uncertainty", "warn_too_coarse",
]


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
        Sampling spacing in radii of curvature (nan where undefined, inf
        where the ball is round: ``TUNING.round_ball``).
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
    """The median residual of the counted points of each kernel width, at least ``TUNING.misfit_floor``.

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
        baselines[int(k)] = max(float(np.median(surface)) if surface.size else 0.0, TUNING.misfit_floor)
    return baselines


def misfits(residual: np.ndarray | None, width: np.ndarray, baselines: dict, factor: float | None = None) -> np.ndarray:
    """Points whose residual exceeds ``factor`` times their width's baseline, shape (n,), bool.

    ``factor``: the fit plan's (:attr:`heatcurv.choice.plan.FitPlan.misfit_factor`); default
    ``TUNING.misfit_factor``, a clean cloud's.
    """
    if residual is None:
        return np.zeros(width.shape[0], dtype=bool)
    factor = TUNING.misfit_factor if factor is None else float(factor)
    widths = np.array(sorted(baselines), dtype=np.int64)
    limit = factor * np.array([baselines[k] for k in widths.tolist()])
    return residual > limit[np.searchsorted(widths, width)]


def resolution(rho: np.ndarray, counted: np.ndarray) -> float:
    """The median counted point's spacing in radii of curvature (``TUNING.resolution_limit``); 0 if none counts.

    Round balls (``rho`` infinite) count, as beyond any limit; undefined ones (NaN) do not.
    """
    values = rho[counted & ~np.isnan(rho)]
    return float(np.median(values)) if values.size else 0.0


def warn_too_coarse(rho: float, stacklevel: int = 2, swamped: bool = False) -> None:
    """Warn that the cloud's resolution ``rho`` (:func:`resolution`) is past ``TUNING.resolution_limit``.

    ``swamped``: the kernel choice measured noise above ``TUNING.strong_noise``
    (:func:`heatcurv.choice.plan.noise_swamps_balls`), as thick as the operator's balls are wide (or no
    surface at all: a volume reads as such noise); round balls then say that, not that the cloud is too
    sparse.
    """
    if np.isinf(rho) and swamped:
        warnings.warn("most of the cloud's balls are round, not flat: its noise is about as thick as they are "
                      "wide, or its points fill a volume instead of lining a surface; every value is marked "
                      "unreliable. Denser sampling makes noise thicker in spacings, not thinner: check that it is "
                      "a surface; a wider neighbourhood (neighbours=, up to 1920) can average over noise that is "
                      "small beside the curvature (check the reliable share and the standard errors).",
                      HeatcurvWarning, stacklevel=stacklevel + 1)
        return
    measure = ("most of its balls are round, not flat: the surface wraps around within them (a part a few "
               "spacings across), or the points fill a volume instead of lining a surface") if np.isinf(rho) else (
        f"a median point's spacing is {rho:.2g} radii of curvature (at most {TUNING.resolution_limit:g}: about 12 "
        "points around a curve), so its neighbourhoods wrap around the surface")
    advice = "Sample it more densely" + (", or check that it is a surface" if np.isinf(rho) else "")
    warnings.warn(f"the cloud is too coarse for its curvature: {measure}; every value is marked unreliable. "
                  f"{advice}.", HeatcurvWarning, stacklevel=stacklevel + 1)


def cloud_flags(inputs: ReliabilityInputs, baselines: dict | None = None, resolution_value: float | None = None,
                stacklevel: int = 2, swamped: bool = False, misfit_factor: float | None = None,
                ) -> tuple[np.ndarray, float]:
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
    swamped : bool, optional
        The noise is as thick as the operator's balls (:func:`heatcurv.choice.plan.noise_swamps_balls`):
        the warning says so.
    misfit_factor : float, optional
        The residual, in its width's baselines, from which a point is a misfit (:func:`misfits`).

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
    reliable = inputs.local & ~misfits(inputs.residual, inputs.width, baselines or {}, misfit_factor)
    rho = resolution(inputs.rho, inputs.counted) if resolution_value is None else resolution_value
    if rho > TUNING.resolution_limit:
        warn_too_coarse(rho, stacklevel + 1, swamped)
        reliable = np.zeros_like(reliable)
    return reliable, rho


@dataclass(frozen=True)
class PrecisionReport:
    """How precise the input coordinates are, and what their rounding made unreliable (``info["precision"]``).

    Attributes
    ----------
    source : str
        Where the precision comes from: ``"float32 coordinates"`` (or float16), ``"float64 values float32
        holds exactly"``, or ``"coordinate_precision"`` (given, e.g. a LAS file's scale).
    largest_error : float
        The largest rounding error of a coordinate, input units: half the step of its grid.
    flagged : int
        Input rows whose curvature the rounding can move by more than ``TUNING.precision_tolerance`` of its
        scale (:func:`imprecise`): not reliable, whatever else flags them.
    uncertainty : ndarray, shape (n,)
        Standard deviation of each row's mean curvature under the rounding, 1/length; nan where it is
        not assessed (``method="paper"``).
    reason : str
        The rule, in words.
    """

    source: str
    largest_error: float
    flagged: int
    uncertainty: np.ndarray
    reason: str


def flattened(noise: float, radius: np.ndarray) -> np.ndarray:
    """Points whose fit the noise flattens by about 10 % or more, shape (n,), bool.

    The heat kernel weighs a neighbour by its distance, noise included: a
    neighbour whose noise moves it towards the centre's tangent plane weighs
    more, so the fitted heights, and the curvatures with them, come out too
    small, by about ``20 (noise / R)^2`` of their value on a noisy sphere (``R``
    the ball radius of the point's fit; docs/accuracy.md). Lepski's rule
    widens the kernel against the noise's variance, not against this bias; a
    cloud with few points for its noise cannot widen it enough, and from
    ``noise > TUNING.noise_flattening * R`` on its values are not reliable.

    Parameters
    ----------
    noise : float
        The kernel choice's noise (:attr:`heatcurv.choice.scale.ScaleChoice.sigma`), length units.
    radius : ndarray, shape (n,)
        Each point's fit ball radius, the same units.
    """
    return noise > TUNING.noise_flattening * np.asarray(radius)


def precision_step(coordinate_precision) -> np.ndarray | None:
    """``coordinate_precision`` checked: the grid step per axis, shape (3,), or None (from the coordinates' type).

    Raises
    ------
    HeatcurvError
        If it is not one number or three, or a step is negative, NaN or infinite.
    """
    if coordinate_precision is None:
        return None
    try:
        step = np.asarray(coordinate_precision, dtype=np.float64)
    except (TypeError, ValueError):
        raise HeatcurvError(f"coordinate_precision must be a number or three (one per axis), got "
                            f"{coordinate_precision!r}") from None
    if step.ndim > 1 or step.size not in (1, 3):
        raise HeatcurvError(f"coordinate_precision must be a number or three (one per axis), got shape {step.shape}")
    if not (np.isfinite(step).all() and (step >= 0).all()):
        raise HeatcurvError(f"coordinate_precision must be finite and at least 0 (the step of the grid the "
                            f"coordinates were rounded to, 0 if exact), got {step.tolist()}")
    return np.broadcast_to(step, (3,)).copy()


def coordinate_rounding(points, coordinate_precision=None) -> tuple[np.ndarray, str] | None:
    """The largest rounding error of each coordinate, and where it comes from; None for exact coordinates.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        The coordinates as given (already validated: finite, shape (n, 3)).
    coordinate_precision : float or array_like of shape (3,), optional
        The step of the grid the coordinates were rounded to, for all axes or per axis, input units (a
        LAS file's scale); 0: exact. Default: from their type. A float32 (or float16) coordinate is
        off by up to half its spacing (``np.spacing``), which grows with its distance from the origin;
        so is a float64 array whose every value float32 holds exactly (a float32 cloud converted; a
        float64 sample of a surface never is). Other float64 and integer coordinates are taken as exact.

    Returns
    -------
    half_step : ndarray, shape (n, 3) or (3,)
        Largest error of each coordinate (per row, or one per axis), input units.
    source : str
        :attr:`PrecisionReport.source`.
    """
    step = precision_step(coordinate_precision)
    if step is not None:
        return (0.5 * step, "coordinate_precision") if step.any() else None
    dtype = getattr(points, "dtype", None)
    if dtype is not None and dtype.kind == "f" and dtype.itemsize < 8:
        narrow = np.asarray(points)
        return np.spacing(np.abs(narrow)).astype(np.float64) * 0.5, f"{dtype.name} coordinates"
    if dtype is not None and dtype.kind != "f":
        return None  # integers (a voxel grid?) are taken as exact: coordinate_precision=1 says otherwise
    values = np.asarray(points, dtype=np.float64)
    with np.errstate(over="ignore"):  # beyond float32's range: inf, not equal
        single = values.astype(np.float32)
    if np.array_equal(single, values):
        return np.spacing(np.abs(single)).astype(np.float64) * 0.5, "float64 values float32 holds exactly"
    return None


def rounding_uncertainty(half_step: np.ndarray, normals: np.ndarray, mean_variance_factor: np.ndarray) -> np.ndarray:
    """Standard deviation of each point's fitted mean curvature under the rounding of the coordinates, shape (m,).

    The rounding's height variance (:func:`rounding_height_variance`, same ``half_step`` and ``normals``) times
    the fit's variance factor ``mean_variance_factor`` (shape (m,), 1/length^4:
    :attr:`heatcurv.fits.chordfit.ChordFit.mean_variance_factor`), which holds the fit's weights and how well its
    neighbours pin its coefficients down.
    """
    return np.sqrt(rounding_height_variance(half_step, normals) * np.maximum(mean_variance_factor, 0.0))


def rounding_height_variance(half_step: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Variance of each point's height along its normal under the rounding of the coordinates, shape (m,).

    Each coordinate's rounding error is uniform within ``+- half_step`` (variance ``half_step^2 / 3``) and
    independent of the others: ``sum(n_c^2 half_step_c^2) / 3``.

    Parameters
    ----------
    half_step : ndarray, shape (m, 3) or (3,)
        Largest rounding error of each coordinate, the fit's length unit.
    normals : ndarray, shape (m, 3)
        Unit normals.
    """
    return np.einsum("ij,ij->i", normals**2, np.broadcast_to(half_step, normals.shape) ** 2) / 3.0


def imprecise(uncertainty: np.ndarray, k1: np.ndarray, k2: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Points whose coordinates are too coarse for their curvature, shape (m,), bool.

    A point is imprecise when ``TUNING.precision_coverage`` times its rounding ``uncertainty``
    (:func:`rounding_uncertainty`) exceeds ``TUNING.precision_tolerance`` of its curvature scale, the larger
    of ``|k1|``, ``|k2|`` and ``TUNING.flat_curvature`` over the radius of its fit's ball.
    """
    with np.errstate(invalid="ignore"):
        scale = np.maximum(np.maximum(np.abs(k1), np.abs(k2)), TUNING.flat_curvature / radius)
        return TUNING.precision_coverage * uncertainty > TUNING.precision_tolerance * scale
