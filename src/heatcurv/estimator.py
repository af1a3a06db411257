"""``heatcurv.estimate``: every field of the paper's pipeline in one call.

    points -> validate, centre, merge duplicates
           -> spacing h (eq 2.6/2.7) -> ball neighbourhood (r = alpha h)
           -> heat-kernel weights (eq 2.8) -> areas (H A = 1, section 2.2)
           -> normals (PCA + one orientation, or given, or a viewpoint)
           -> mean-curvature normal K (eq 2.10) -> mean curvature (eq 2.11/2.12)
           -> tensor fit of the edge curvatures (section 3, eq 3.1)
           -> k1 >= k2, d1, d2, Gaussian = k1 k2
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .areas import ball_area_factor, density_areas
from .border import border_points
from .errors import HeatcurvError
from .mean_curvature import mean_curvature, mean_curvature_normal
from .normals import as_viewpoint, orient_normals, orient_towards_viewpoint, pca_normals
from .backend import threads
from .pipeline import Options, build_operator, resolve_options
from .progress import StageClock
from .principal import principal_fit
from .chordfit import ChordFit
from .scale import fit_blocks, select_scale
from .validation import prepare_normals

__all__ = ["CurvatureResult", "estimate"]

#: PCA planarity below which a neighbourhood is not treated as a surface patch.
PLANARITY_MIN = 0.05


@dataclass(frozen=True)
class CurvatureResult:
    """Differential geometry of a point cloud, one row per input point, in input order.

    Attributes
    ----------
    normals : ndarray, shape (n, 3)
        Unit normals, consistently oriented (closed surfaces: outward), or the
        caller's normals normalised.
    mean : ndarray, shape (n,)
        Signed mean curvature, 1/length; positive where the surface bends
        away from its normal (sphere, outward normals: +1/R).
    gaussian : ndarray, shape (n,)
        Gaussian curvature ``k1 * k2``, 1/length^2.
    k1, k2 : ndarray, shape (n,)
        Principal curvatures, ``k1 >= k2``.
    d1, d2 : ndarray, shape (n, 3)
        Unit principal directions, tangent, ``d1 x d2 = normals``. Their sign
        is arbitrary; at umbilic points (sphere, plane) any tangent pair.
    area : ndarray, shape (n,)
        Per-point area, length^2; the sum estimates the surface area.
    reliable : ndarray, shape (n,), bool
        False where the values are not to be trusted: the point's ball held
        too few neighbours (nearest neighbours were used instead), its
        neighbourhood is not surface-like (PCA planarity < 0.05), the tensor
        fit was ill-posed, its area came out non-positive, or it is a border
        point; everywhere if the area system did not converge (a
        ``HeatcurvWarning`` says so).
    border : ndarray, shape (n,), bool
        Points whose fit's ball is cut by the border of an open surface
        (:mod:`heatcurv.border`): their values come from one-sided
        neighbourhoods. Noisy clouds are fitted with wider balls, so their
        border band is wider.
    spacing : ndarray, shape (n,)
        The spacing ``h`` of the heat kernel (``t = m h^2``; eq 2.6, 2.7, or
        ``d_k / alpha``) at each point: the kernel of the Laplace-Beltrami
        operator and of ``mean_curvature_normal``. The chord fit may use a
        wider kernel; ``info["scale"]`` says which.
    neighbours : ndarray, shape (n,), int
        Points in each heat-kernel ball (the point itself excluded).
    mean_curvature_normal : ndarray, shape (n, 3)
        ``K = L x`` of eq 2.10, approximately ``2 mean * normals``.
    options : Options
        The resolved options the result was computed with.
    info : dict
        ``n_distinct`` (points after merging duplicates), ``area_solve``
        (solver, iterations, residual), ``timings`` (seconds per stage), and
        for the chord fit ``scale``: the kernel chosen (``k`` neighbours,
        ``fit`` label, ``radius``: 99th percentile of its ball radii), the
        noise estimate ``sigma`` (length units) and ``relative_noise``
        (``sigma / h``).
    """

    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    area: np.ndarray
    reliable: np.ndarray
    border: np.ndarray
    spacing: np.ndarray
    neighbours: np.ndarray
    mean_curvature_normal: np.ndarray
    options: Options
    info: dict = field(default_factory=dict)

    FIELDS = ("normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "area")

    def __len__(self) -> int:
        return int(self.mean.shape[0])

    def __repr__(self) -> str:
        return (
            f"CurvatureResult(n={len(self)}, method={self.options.method!r}, "
            f"total_area={self.area.sum():.6g}, reliable={int(self.reliable.sum())}/{len(self)})"
        )

    def as_dict(self) -> dict:
        """The per-point arrays by name (``FIELDS`` plus ``reliable``)."""
        return {name: getattr(self, name) for name in self.FIELDS + ("reliable",)}


def estimate(
    points,
    normals=None,
    *,
    method: str = "default",
    alpha: float | None = None,
    m: float | None = None,
    spacing: str | None = None,
    gamma: float | None = None,
    k_local: int | None = None,
    neighbors: int | None = None,
    area_method: str | None = None,
    mean_formula: str | None = None,
    fit: str | None = None,
    scale=None,
    area_solver: str | None = None,
    viewpoint=None,
    min_neighbors: int | None = None,
    workers: int | None = None,
    progress=None,
) -> CurvatureResult:
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
        option below overrides the preset (``heatcurv.METHODS`` lists both).
    alpha : float, optional
        Ball radius ``r = alpha h`` (paper: 4; default: 2).
    m : float, optional
        ``t = m h^2`` (1/4).
    spacing : {"global", "local", "density"}, optional
        ``h`` from eq 2.6, eq 2.7 or the density (``d_k / alpha``).
    gamma : float, optional
        Blend of eq 2.7 (0.25).
    k_local : int, optional
        Neighbours of eq 2.7's min/max (8).
    neighbors : int, optional
        Neighbours in the density ball, and the narrowest kernel of the
        chord fit (60).
    area_method : {"system", "density"}, optional
        Areas from ``H A = 1`` (paper) or the density estimate (default).
    mean_formula : {"projection", "norm"}, optional
        Eq 2.12 or eq 2.11, where the mean curvature comes from the quadrature
        (``fit="constrained"``).
    fit : {"chord", "constrained", "unconstrained"}, optional
        The chord fit with tilt and cubic terms (default); the paper's tensor
        fit with eq 3.1's constraints; or the tensor fit without them.
    scale : "auto" or int, optional
        Kernel of the chord fit: chosen from the noise (``"auto"``), or a
        fixed neighbour count. ``res.info["scale"]`` reports the choice.
    area_solver : {"auto", "cg", "bicgstab", "direct"}, optional
        Solver of ``H A = 1`` (``area_method="system"``).
    viewpoint : array_like, shape (3,), optional
        Sensor position, in the input coordinates: orient every estimated
        normal towards it instead of propagating one orientation.
    min_neighbors : int, optional
        Fewest neighbours per point (6).
    workers : int, optional
        Threads for the k-d tree queries and the compiled kernels (-1: all
        cores; 1: one thread).
    progress : callable, optional
        Called as ``progress(stage, fraction)`` as the stages run
        (:mod:`heatcurv.progress`); the command line's progress bars use it.

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
    opts = resolve_options(
        method,
        alpha=alpha,
        m=m,
        spacing=spacing,
        gamma=gamma,
        k_local=k_local,
        neighbors=neighbors,
        area_method=area_method,
        mean_formula=mean_formula,
        fit=fit,
        scale=scale,
        area_solver=area_solver,
        min_neighbors=min_neighbors,
        workers=workers,
    )
    if normals is not None and viewpoint is not None:
        raise HeatcurvError("give either normals or a viewpoint, not both")
    vp = None if viewpoint is None else as_viewpoint(viewpoint)
    with threads(opts.workers):
        op = build_operator(points, opts, progress=progress)
        clock = StageClock(progress, dict(op.timings))
        X, nbhd, prepared = op.points, op.neighbourhood, op.prepared

        planarity = np.ones(X.shape[0])
        if normals is not None:
            with clock.stage("normals"):
                nrm = prepare_normals(normals, prepared)
        else:
            with clock.stage("normals"):
                nrm, planarity = pca_normals(X, nbhd, taper=opts.taper)
            with clock.stage("orientation"):
                if vp is not None:
                    nrm = orient_towards_viewpoint(X, nrm, vp - prepared.offset)
                else:
                    nrm = orient_normals(X, nrm, nbhd, op.areas)

        with clock.stage("mean"):
            # the heat kernel is computed pair by pair unless the operator already holds it
            K = mean_curvature_normal(X, nbhd, op.stored_weights, op.areas, op.h, opts.m)
            mean = mean_curvature(K, nrm, opts.mean_formula)

        info = {"n_distinct": prepared.n_distinct, "area_solve": op.area_solve}
        with clock.stage("principal"):
            if opts.fit == "chord":
                fit, areas, border, info["scale"] = _chord_estimate(op, nrm, normals is not None, clock)
                pc, nrm = fit.principal, fit.normals
                mean = pc.mean
            else:
                # The paper's fit weights w_ij = W_ij |xi-xj|^2 A_j (section 3). Irregular
                # samples can give negative A_j; a least-squares objective with negative
                # weights has no minimum, so those neighbours get weight zero.
                pair_w = op.weights * nbhd.distances**2 * np.maximum(op.areas, 0.0)[nbhd.indices]
                pc = principal_fit(X, nbhd, nrm, pair_w, mean=mean, constrained=opts.fit == "constrained")
                if opts.fit == "unconstrained":
                    mean = pc.mean
                areas = op.areas
                # border of open surfaces, on the neighbourhood the curvature was fitted on
                border = border_points(X, nbhd, nrm, taper=opts.taper)
    timings = clock.timings

    reliable = ~nbhd.augmented & (planarity >= PLANARITY_MIN) & pc.well_posed & (areas > 0) & ~border
    reliable &= op.area_solve.converged
    info["timings"] = timings
    back = prepared.to_input_order
    return CurvatureResult(
        normals=back(nrm),
        mean=back(mean),
        gaussian=back(pc.gaussian),
        k1=back(pc.k1),
        k2=back(pc.k2),
        d1=back(pc.d1),
        d2=back(pc.d2),
        area=prepared.share_among_duplicates(areas),
        reliable=back(reliable),
        border=back(border),
        spacing=back(op.h),
        neighbours=back(nbhd.counts),
        mean_curvature_normal=back(K),
        options=opts,
        info=info,
    )


def _chord_estimate(op, normals, keep_normals: bool, clock=None):
    """The chord fit at the kernel ``op.options.scale`` asks for (or chooses), block by block.

    Returns the fit, the areas (recomputed on the fit's kernel when it is
    wider than the base one, so noise does not inflate them), the border flags
    (on the fit's ball) and the scale record for ``info``. Each block's
    neighbourhood is dropped once its fit, areas and border flags are done.
    """
    opts, X = op.options, op.points
    choice = select_scale(
        X, op.tree, normals, op.areas, base_k=int(opts.neighbors), alpha=opts.alpha,
        fixed_k=None if opts.scale == "auto" else int(opts.scale), workers=opts.workers,
    )
    base = op.neighbourhood
    reuse_base = opts.spacing == "density" and choice.scale.k == int(opts.neighbors)
    n = X.shape[0]
    areas = np.empty(n)
    border = np.empty(n, dtype=bool)
    radius = np.empty(n)
    fits = []
    for lo, hi, nbhd, fit, fraction in fit_blocks(
        X, op.tree, normals, op.areas, choice.scale, base=base if reuse_base else None, alpha=opts.alpha,
        passes=1 if keep_normals else 2, workers=opts.workers,
    ):
        pc = fit.principal
        if opts.area_method == "density":
            # wider kernels: areas from their own, less noisy, density count
            own = op.areas[lo:hi] if choice.scale.k <= opts.neighbors else density_areas(nbhd, fraction=fraction)
            area_radius = base.radius[lo:hi] if choice.scale.k <= opts.neighbors else nbhd.radius
            areas[lo:hi] = own * ball_area_factor(area_radius, pc.k1, pc.k2)
        else:
            areas[lo:hi] = op.areas[lo:hi]
        fit_normals = normals[lo:hi] if keep_normals else fit.normals
        border[lo:hi] = border_points(X, nbhd, fit_normals, taper=opts.taper, centres=X[lo:hi])
        radius[lo:hi] = nbhd.radius
        fits.append(replace(fit, normals=normals[lo:hi]) if keep_normals else fit)
        if clock is not None:
            clock.report("principal", hi / n)
    fit = ChordFit.concatenate(fits)
    record = {
        "k": choice.scale.k,
        "median_h": float(np.median(radius / opts.alpha)),
        "radius": float(np.percentile(radius, 99)),
        "fit": choice.scale.label,
        "sigma": choice.sigma,
        "relative_noise": choice.relative_noise,
        "candidates": [c.label for c in choice.candidates],
        "sd": choice.sd,
    }
    return fit, areas, border, record
