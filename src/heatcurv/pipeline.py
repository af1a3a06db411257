"""Options, method presets and the shared heat-kernel operator (the first stages).

``build_operator`` runs the stages every estimator shares, once:
validation -> k-d tree -> spacing h (eq 2.6 / 2.7, or density) -> ball
neighbourhood of radius ``alpha h`` -> heat-kernel weights (eq 2.8) -> areas
(``H A = 1``, section 2.2, or a density estimate). :func:`heatcurv.estimate` and :func:`heatcurv.laplacian` start
from its result.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from .areas import AreaSolve, density_areas, point_areas
from .backend import threads
from .errors import HeatcurvError, HeatcurvWarning
from .kernel import heat_kernel_weights
from .neighbourhood import Neighbourhood, ball_neighbourhood, knn_neighbourhood
from .progress import StageClock
from .spacing import spacing as compute_spacing
from .validation import PreparedPoints, prepare_points

__all__ = ["Options", "METHODS", "resolve_options", "HeatKernelOperator", "build_operator"]


@dataclass(frozen=True)
class Options:
    """Every knob of the pipeline, with the paper's names where the paper has one.

    Attributes
    ----------
    method : str
        Name of the preset the other values came from.
    alpha : float
        Ball radius in units of the spacing, ``r = alpha h`` (paper: 3.5-4.5).
    m : float
        Diffusion-time constant, ``t = m h^2`` (eq 2.8; paper: 1/4).
    spacing : {"global", "local", "density"}
        ``h`` from eq 2.6 (one value), eq 2.7 (per point), or the density
        radius ``d_k / alpha`` with ``k = neighbors``.
    gamma : float
        Blend of eq 2.7 (paper: 0.1-0.5).
    k_local : int
        Nearest neighbours the min/max of eq 2.7 run over.
    neighbors : int
        Neighbours in the ball of the density spacing, and the narrowest
        kernel of the chord fit.
    area_method : {"system", "density"}
        Areas from the paper's ``H A = 1`` (section 2.2) or from the
        flat-top density estimate (:func:`heatcurv.areas.density_areas`).
    mean_formula : {"norm", "projection"}
        Mean curvature as ``1/2 |K|`` signed (eq 2.11) or ``1/2 K . n`` (eq 2.12),
        for the fits that take it from the quadrature.
    fit : {"constrained", "unconstrained", "chord"}
        Principal fit with the constraints of eq 3.1, free, or the chord fit
        with tilt and cubic terms (:mod:`heatcurv.chordfit`).
    scale : "auto" or int
        Kernel of the chord fit: ``"auto"`` chooses it from the measured noise
        (:mod:`heatcurv.scale`); an integer ``k`` fixes it to ``k`` neighbours.
    area_solver : {"auto", "cg", "bicgstab", "direct"}
        Solver of ``H A = 1``.
    taper : bool
        Weight the PCA and the border test by a flat-top taper that falls to
        0 at the ball's edge (:func:`heatcurv.kernel.ball_taper`), so results
        are continuous in the points; False is the paper's plain PCA.
    min_neighbors : int
        Fewest neighbours a point may have; sparser points get their nearest ones.
    workers : int
        Threads for the k-d tree queries and the compiled kernels (-1: all
        cores; 1: one thread, e.g. when the caller parallelises over clouds).
    """

    method: str = "default"
    alpha: float = 2.0
    m: float = 0.25
    spacing: str = "density"
    gamma: float = 0.25
    k_local: int = 8
    neighbors: int = 60
    area_method: str = "density"
    mean_formula: str = "projection"
    fit: str = "chord"
    scale: object = "auto"
    area_solver: str = "auto"
    taper: bool = True
    min_neighbors: int = 6
    workers: int = -1


#: The presets of ``method=``.
#:
#: ``"paper"`` follows the paper literally and is the reproducible reference:
#: eq 2.6 spacing, ``alpha = 4``, ``m = 1/4``, areas from ``H A = 1``, mean
#: curvature ``1/2 |K|`` (eq 2.11), the constrained fit of eq 3.1.
#:
#: ``"default"`` replaces the stages that fail on irregular and noisy clouds,
#: each by a named option: spacing from density (``spacing="density"``, the
#: ball holds 60 neighbours, ``alpha = 2``), areas from a density estimate
#: (``area_method="density"``), and the chord fit with tilt and cubic terms at
#: a noise-adapted kernel (``fit="chord"``, ``scale="auto"``). The heat kernel
#: (``t = h^2/4``, eq 2.8) weights the fit, and the mean-curvature normal of
#: eq 2.10 is still computed (``result.mean_curvature_normal``, used by the
#: feature detector).
METHODS: dict[str, Options] = {
    "paper": Options(
        method="paper", alpha=4.0, spacing="global", area_method="system", mean_formula="norm",
        fit="constrained", scale=None, taper=False,
    ),
    "default": Options(method="default"),
}

_CHOICES = {
    "spacing": ("global", "local", "density"),
    "area_method": ("system", "density"),
    "mean_formula": ("norm", "projection"),
    "fit": ("constrained", "unconstrained", "chord"),
    "area_solver": ("auto", "cg", "bicgstab", "direct"),
}


def resolve_options(method: str = "default", **overrides) -> Options:
    """The preset ``method`` with the non-None ``overrides`` applied, validated.

    Raises
    ------
    HeatcurvError
        On an unknown method, option or choice, or a value out of range.
    """
    if method not in METHODS:
        raise HeatcurvError(f"unknown method {method!r}; choose one of {', '.join(sorted(METHODS))}")
    given = {k: v for k, v in overrides.items() if v is not None}
    unknown = set(given) - set(Options.__dataclass_fields__)
    if unknown:
        raise HeatcurvError(f"unknown option(s) {', '.join(sorted(unknown))}")
    opts = replace(METHODS[method], **given)
    for name, allowed in _CHOICES.items():
        if getattr(opts, name) not in allowed:
            raise HeatcurvError(f"{name} must be one of {', '.join(map(repr, allowed))}, got {getattr(opts, name)!r}")
    if not (np.isfinite(opts.alpha) and opts.alpha > 0):
        raise HeatcurvError(f"alpha must be a positive number (paper: 3.5-4.5), got {opts.alpha}")
    if not (np.isfinite(opts.m) and opts.m > 0):
        raise HeatcurvError(f"m must be a positive number (paper: 1/4), got {opts.m}")
    if not 0 <= opts.gamma <= 1:
        raise HeatcurvError(f"gamma must lie in [0, 1] (paper: 0.1-0.5), got {opts.gamma}")
    if int(opts.min_neighbors) < 3:
        raise HeatcurvError(f"min_neighbors must be at least 3 (the tensor fit has 3 unknowns), got {opts.min_neighbors}")
    if int(opts.neighbors) < 20:
        raise HeatcurvError(f"neighbors must be at least 20 (the chord fit has 9 unknowns), got {opts.neighbors}")
    if opts.fit == "chord":
        if opts.scale is None:
            opts = replace(opts, scale="auto")
        if not (opts.scale == "auto" or (isinstance(opts.scale, (int, np.integer)) and opts.scale >= 20)):
            raise HeatcurvError(f"scale must be 'auto' or a neighbour count >= 20, got {opts.scale!r}")
    return opts


@dataclass
class HeatKernelOperator:
    """The shared stages' output, computed once per cloud.

    Attributes
    ----------
    prepared : PreparedPoints
        Distinct centred points and the map back to input rows.
    tree : scipy.spatial.cKDTree
        k-d tree on ``prepared.points``.
    h : ndarray, shape (m,)
        Spacing per distinct point.
    neighbourhood : Neighbourhood
        Ball neighbours, radius ``alpha h``.
    areas : ndarray, shape (m,)
        Per-point areas.
    area_solve : AreaSolve
        How ``H A = 1`` was solved.
    options : Options
    timings : dict of str to float
        Seconds per stage.
    """

    prepared: PreparedPoints
    tree: cKDTree
    h: np.ndarray
    neighbourhood: Neighbourhood
    areas: np.ndarray
    area_solve: AreaSolve
    options: Options
    timings: dict = field(default_factory=dict)
    _weights: np.ndarray | None = field(default=None, repr=False)

    @property
    def stored_weights(self) -> np.ndarray | None:
        """``W_ij`` if already computed (the area system needs them), else None."""
        return self._weights

    @property
    def weights(self) -> np.ndarray:
        """Heat-kernel weights ``W_ij`` of every pair, shape ``(nnz,)`` (computed on first use)."""
        if self._weights is None:
            self._weights = heat_kernel_weights(self.neighbourhood, self.h, self.options.m)
        return self._weights

    @property
    def m(self) -> float:
        return self.options.m

    @property
    def points(self) -> np.ndarray:
        """Distinct centred points, shape ``(m, 3)``."""
        return self.prepared.points


def build_operator(points, options: Options | None = None, progress=None, **overrides) -> HeatKernelOperator:
    """Run validation, spacing, neighbourhood, weights and areas once.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Point coordinates.
    options : Options, optional
        Resolved options; if omitted, ``resolve_options(**overrides)``.
    progress : callable, optional
        ``progress(stage, fraction)`` (:mod:`heatcurv.progress`).
    **overrides
        ``method`` and any :class:`Options` field.

    Returns
    -------
    HeatKernelOperator
    """
    if options is None:
        options = resolve_options(**overrides)
    clock = StageClock(progress)
    with threads(options.workers):
        with clock.stage("validate"):
            need = int(options.min_neighbors) + 1
            if options.spacing == "density" or options.fit == "chord":
                need = max(need, int(options.neighbors) + 1)
            prepared = prepare_points(points, min_points=need)
            # k-d tree leaf order: neighbours close in memory, every later gather cache-friendly
            prepared = prepared.reordered(cKDTree(prepared.points).indices)
            X = prepared.points
            tree = cKDTree(X)

        if options.spacing == "density":
            # the ball of radius d_k = alpha h holds the k nearest neighbours: one query gives both
            with clock.stage("neighbours"):
                nbhd = knn_neighbourhood(X, int(options.neighbors), tree=tree, workers=options.workers)
            with clock.stage("spacing"):
                h = nbhd.radius / options.alpha
        else:
            with clock.stage("spacing"):
                if options.spacing == "local" and options.k_local >= prepared.n_distinct:
                    raise HeatcurvError(f"too few points for the local spacing over {options.k_local} neighbours")
                h = compute_spacing(X, options.spacing, gamma=options.gamma, k=options.k_local, tree=tree, workers=options.workers)
            with clock.stage("neighbours"):
                nbhd = ball_neighbourhood(
                    X, options.alpha * h, tree=tree, min_neighbors=int(options.min_neighbors), workers=options.workers
                )
        if not np.all(h > 0):
            raise HeatcurvError("a point's spacing is zero; this should not happen after merging duplicates")

        with clock.stage("areas"):
            if options.area_method == "density":
                weights = None  # computed on first use (HeatKernelOperator.weights), not stored on large clouds
                areas, info = density_areas(nbhd), AreaSolve("density", 0, 0.0, True)
            else:
                weights = heat_kernel_weights(nbhd, h, options.m)
                areas, info = point_areas(nbhd, weights, h, options.m, solver=options.area_solver, return_info=True)
    if not info.converged:
        warnings.warn(
            f"the area system H A = 1 did not converge ({info.solver}: {info.iterations} iterations, "
            f"relative residual {info.residual:.2g}); areas and everything built on them are marked "
            "unreliable. Try area_solver='direct', a smaller m or a larger alpha.",
            HeatcurvWarning,
            stacklevel=3,
        )
    timings = clock.timings
    return HeatKernelOperator(prepared, tree, h, nbhd, areas, info, options, timings, weights)
