"""The shared heat-kernel operator: the stages every estimator starts from, as one object.

:meth:`HeatKernelOperator.from_points` runs, once per cloud and each timed
under its own name:

    validate    checks, centring, duplicate merging, k-d tree leaf order
    neighbours  ball neighbourhood (radius ``alpha h``; the density spacing's
                ball is the ``neighbours`` nearest points, one query; with
                ``radius=``, the ball of that radius)
    spacing     ``h``: eq 2.6, eq 2.7, the density radius ``d_k / alpha``, or
                ``radius / alpha``
    areas       per-point areas: ``H A = 1`` (section 2.2) or the density estimate

The object then answers the paper's operator questions without recomputing
them: the heat-kernel weights ``W_ij`` (eq 2.8), the Laplace-Beltrami matrix
(eq 2.9), ``L`` applied to a field, and the mean-curvature normal ``K = L x``
(eq 2.10). :func:`heatcurv.estimate` and the paper path of :func:`heatcurv.laplacian`
(in :mod:`heatcurv.operators.point_laplacian`) start from it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..backend import threads
from ..errors import HeatcurvError, HeatcurvWarning
from ..geometry.neighbourhood import Neighbourhood, ball_neighbourhood, knn_neighbourhood
from ..geometry.spacing import spacing as compute_spacing
from ..geometry.validation import PreparedPoints, prepare_points
from ..options import Options, check_options_for_cloud, resolve_options
from ..progress import StageClock
from .areas import AreaSolve, density_areas, point_areas
from .kernel import heat_kernel_weights
from .laplace_beltrami import laplace_beltrami_matrix
from .mean_curvature import mean_curvature_normal

__all__ = ["HeatKernelOperator", "build_operator"]


@dataclass
class HeatKernelOperator:
    """The heat-kernel operator of one cloud: neighbourhood, spacing, weights and areas.

    Build it with :meth:`from_points` (or :func:`build_operator`); all arrays
    are over the distinct, centred points in k-d tree leaf order
    (``prepared.to_input_order`` maps them back), in the length unit
    ``prepared.unit`` (1, the input's unit, unless the cloud spans less than
    ``2**-40`` or more than ``2**40``: :data:`heatcurv.geometry.validation.UNIT_BAND`).

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

    @classmethod
    def from_points(
        cls, points, options: Options | None = None, progress=None, frame=None, knn=None, **overrides
    ) -> HeatKernelOperator:
        """Run validation, neighbourhood, spacing and areas once.

        Parameters
        ----------
        points : array_like, shape (n, 3)
            Point coordinates.
        options : Options, optional
            Resolved options; if omitted, ``resolve_options(**overrides)``.
        progress : callable, optional
            ``progress(stage, fraction)`` (:mod:`heatcurv.progress`).
        frame : heatcurv.choice.choices.CloudFrame, optional
            The whole cloud's frame when ``points`` are a part of it (a tile).
        knn : callable, optional
            ``knn(prepared, tree, k, workers) -> Neighbourhood``: the ``k`` nearest
            neighbours of every distinct point (rows in ``prepared``'s order),
            as :func:`~heatcurv.geometry.neighbourhood.knn_neighbourhood`
            returns them, when they are known already (a tile whose
            neighbourhoods the survey computed, :mod:`heatcurv.tiles.neighbours`).
            Used with ``spacing="density"`` (the default); default: queried.
            If it has a method ``areas(prepared)`` that returns the density
            areas of those neighbourhoods (shape (m,), or None), they are not
            computed again.
        **overrides
            ``method`` and any :class:`~heatcurv.options.Options` field.

        Returns
        -------
        HeatKernelOperator

        Warns
        -----
        HeatcurvWarning
            When ``H A = 1`` did not converge (everything built on the areas
            is then marked unreliable).
        """
        if options is None:
            options = resolve_options(**overrides)
        clock = StageClock(progress)
        with threads(options.workers):
            with clock.stage("validate"):
                prepared = _prepare(points, options, frame)
                tree = cKDTree(prepared.points)
            nbhd, h = _neighbourhood_and_spacing(prepared, tree, options, clock, knn)
            with clock.stage("areas"):
                if options.area_method == "density":
                    weights = None  # computed on first use (.weights), not stored on large clouds
                    areas = _known_areas(knn, prepared, options)
                    areas = density_areas(nbhd) if areas is None else areas
                    solve = AreaSolve("density", 0, 0.0, True)
                else:
                    weights = heat_kernel_weights(nbhd, h, options.m)
                    areas, solve = point_areas(
                        nbhd, weights, h, options.m, solver=options.area_solver, return_info=True
                    )
        if not solve.converged:
            warnings.warn(
                f"the area system H A = 1 did not converge ({solve.solver}: {solve.iterations} iterations, "
                f"relative residual {solve.residual:.2g}); areas and everything built on them are marked "
                "unreliable. Try area_solver='direct', a smaller m or a larger alpha.",
                HeatcurvWarning,
                stacklevel=3,
            )
        return cls(prepared, tree, h, nbhd, areas, solve, options, clock.timings, weights)

    # ------------------------------------------------------------------ data

    @property
    def points(self) -> np.ndarray:
        """Distinct centred points, shape ``(m, 3)``."""
        return self.prepared.points

    @property
    def m(self) -> float:
        """Diffusion-time constant of ``t = m h^2``."""
        return self.options.m

    @property
    def stored_weights(self) -> np.ndarray | None:
        """``W_ij`` if already computed (the area system needs them), else None."""
        return self._weights

    @property
    def weights(self) -> np.ndarray:
        """Heat-kernel weights ``W_ij`` of every pair (eq 2.8), shape ``(nnz,)``; computed on first use."""
        if self._weights is None:
            self._weights = heat_kernel_weights(self.neighbourhood, self.h, self.options.m)
        return self._weights

    # ------------------------------------------------------------- operators

    def matrix(self) -> sp.csr_matrix:
        """The Laplace-Beltrami matrix ``L`` of eq 2.9 over the distinct points, shape ``(m, m)``."""
        return laplace_beltrami_matrix(self.neighbourhood, self.weights, self.areas, self.h, self.m)

    def apply(self, values: np.ndarray) -> np.ndarray:
        """``L f`` (eq 2.9) for a field on the distinct points, shape ``(m,)`` or ``(m, c)``."""
        values = np.asarray(values, dtype=np.float64)
        if values.shape[0] != self.points.shape[0]:
            raise HeatcurvError(f"the field has {values.shape[0]} rows, the operator {self.points.shape[0]} points")
        return self.matrix() @ values

    def mean_curvature_normal(self) -> np.ndarray:
        """The mean-curvature normal ``K = L x`` of eq 2.10, shape ``(m, 3)``, without assembling ``L``.

        Uses the stored weights when the area system computed them, else the
        heat kernel pair by pair (no ``(nnz,)`` array on large clouds).
        """
        return mean_curvature_normal(self.points, self.neighbourhood, self._weights, self.areas, self.h, self.m)


def _prepare(points, options: Options, frame=None) -> PreparedPoints:
    """Validated, centred, distinct points in k-d tree leaf order (cache-friendly gathers)."""
    need = int(options.min_neighbours) + 1
    if options.radius is None and (options.spacing == "density" or options.fit == "chord"):
        need = max(need, int(options.neighbours) + 1)
    prepared = prepare_points(points, min_points=need, frame=frame)
    # the limits the cloud sets (neighbour counts below its size, a radius within its extent)
    diagonal = float(np.linalg.norm(np.ptp(prepared.points, axis=0))) * prepared.unit
    check_options_for_cloud(options, prepared.n_distinct, diagonal)
    return prepared.reordered(cKDTree(prepared.points).indices)


def _neighbourhood_and_spacing(prepared: PreparedPoints, tree: cKDTree, options: Options, clock: StageClock,
                               knn=None):
    """The ball neighbourhood and the spacing ``h``, each timed as its own stage (``knn``: :meth:`from_points`)."""
    X = prepared.points
    if options.radius is not None:
        # one physical ball for every point: h = radius / alpha (radius given in input units)
        radius = float(options.radius) / prepared.unit
        with clock.stage("spacing"):
            h = np.full(X.shape[0], radius / options.alpha)
        with clock.stage("neighbours"):
            nbhd = ball_neighbourhood(
                X, radius, tree=tree, min_neighbours=int(options.min_neighbours),
                workers=options.workers,
            )
    elif options.spacing == "density":
        # the ball of radius d_k = alpha h holds the k nearest neighbours: one query gives both
        with clock.stage("neighbours"):
            k = int(options.neighbours)
            if knn is None:
                nbhd = knn_neighbourhood(X, k, tree=tree, workers=options.workers)
            else:  # known already (a tile whose survey queried them)
                nbhd = knn(prepared, tree, k, options.workers)
        with clock.stage("spacing"):
            h = nbhd.radius / options.alpha
    else:
        with clock.stage("spacing"):
            if options.spacing == "local" and options.k_local >= prepared.n_distinct:
                raise HeatcurvError(f"too few points for the local spacing over {options.k_local} neighbours")
            h = compute_spacing(
                X, options.spacing, gamma=options.gamma, k=options.k_local, tree=tree, workers=options.workers
            )
        with clock.stage("neighbours"):
            nbhd = ball_neighbourhood(
                X, options.alpha * h, tree=tree, min_neighbours=int(options.min_neighbours), workers=options.workers
            )
    if not np.all(h > 0):
        raise HeatcurvError("a point's spacing is zero; this should not happen after merging duplicates")
    return nbhd, h


def _known_areas(knn, prepared: PreparedPoints, options: Options) -> np.ndarray | None:
    """The density areas ``knn`` knows (:meth:`HeatKernelOperator.from_points`), None if it knows none."""
    known = getattr(knn, "areas", None)
    if known is None or options.radius is not None or options.spacing != "density":
        return None
    return known(prepared)


def build_operator(points, options: Options | None = None, progress=None, **overrides) -> HeatKernelOperator:
    """:meth:`HeatKernelOperator.from_points` as a function (same parameters).

    Examples
    --------
    >>> from heatcurv import surfaces
    >>> from heatcurv.operators.operator import build_operator
    >>> pts = surfaces.Sphere().sample(1500, "fibonacci").points
    >>> build_operator(pts, method="paper").matrix().shape
    (1500, 1500)
    """
    return HeatKernelOperator.from_points(points, options, progress, **overrides)
