"""Per-point areas from the unit mass of the heat kernel (paper section 2.2).

The heat kernel integrates to one over the surface, ``int H^t(x, y) dy = 1``.
Discretised over the ball with unknown per-point areas ``A_j`` this gives, for
every point ``i``, the linear system

    sum_{j in B(x_i)} H_ij A_j = 1,   H_ij = exp(-|xi-xj|^2 / (4 t_i)) / (4 pi t_i),

which is ``(1/(pi h^2)) sum_j exp(-|xi-xj|^2/h^2) A_j = 1`` at ``m = 1/4``.
The ball includes ``x_i`` itself, so ``H`` has the diagonal ``1/(4 pi t_i)``.
With the global spacing (eq 2.6) ``H`` is symmetric and, on regular samples,
well conditioned: conjugate gradients converge in a few tens of iterations.
On irregular samples it is not: the solution goes negative and the total
area drifts (-50 % on a random torus), with any solver.

:func:`density_areas` is the default estimator's replacement: a local
density estimate with no linear solve, accurate on lattices and on random
samples alike (see its docstring for the derivation).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._kernels import segment as kernels
from ..errors import HeatcurvError
from ..geometry.neighbourhood import Neighbourhood
from ..tuning import TUNING
from .kernel import TAPER_START, area_normalisation, flat_top

__all__ = [
    "fit_areas",
    "area_matrix", "point_areas", "AreaSolve", "density_areas", "taper_sums", "ball_area_factor", "cut_ball_coverage",
]


@dataclass(frozen=True)
class AreaSolve:
    """How the area system was solved.

    Attributes
    ----------
    solver : str
        ``"cg"``, ``"bicgstab"`` or ``"direct"``.
    iterations : int
        Iterations of the iterative solver (0 for ``"direct"``).
    residual : float
        Relative residual ``|H A - 1| / |1|`` of the returned areas.
    converged : bool
        Whether the residual reached the requested tolerance.
    """

    solver: str
    iterations: int
    residual: float
    converged: bool


def fit_areas(areas: np.ndarray, excluded: np.ndarray) -> np.ndarray:
    """The areas weighting a fit, shape (n,): negative ones (the paper's ``H A = 1`` on irregular samples) 0,
    because a least-squares fit with negative weights has no minimum, and ``excluded`` points (outliers) 0."""
    return np.where(excluded, 0.0, np.maximum(areas, 0.0))


def area_matrix(nbhd: Neighbourhood, weights: np.ndarray, h: np.ndarray, m: float = 0.25) -> sp.csr_matrix:
    """The matrix ``H`` of ``H A = 1`` (section 2.2), diagonal included.

    Parameters
    ----------
    nbhd : Neighbourhood
        Neighbour pairs (point itself excluded).
    weights : ndarray, shape (nnz,)
        ``W_ij`` from :func:`heatcurv.operators.kernel.heat_kernel_weights`.
    h : ndarray, shape (n,)
        Spacing per point.
    m : float, optional
        Diffusion-time constant.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n, n)
        ``H_ij = W_ij / (4 pi t_i)``, ``H_ii = 1 / (4 pi t_i)``.
    """
    n = nbhd.n_points
    scale = area_normalisation(h, m)
    off = sp.csr_matrix(
        (weights * np.repeat(scale, nbhd.counts), nbhd.indices, nbhd.indptr), shape=(n, n)
    )
    return (off + sp.diags(scale)).tocsr()


def point_areas(
    nbhd: Neighbourhood,
    weights: np.ndarray,
    h: np.ndarray,
    m: float = 0.25,
    solver: str = "auto",
    rtol: float = 1e-8,
    maxiter: int | None = 1000,
    return_info: bool = False,
):
    """Solve ``H A = 1`` for the per-point areas ``A`` (section 2.2).

    Parameters
    ----------
    nbhd : Neighbourhood
        Neighbour pairs.
    weights : ndarray, shape (nnz,)
        Heat-kernel weights ``W_ij``.
    h : ndarray, shape (n,)
        Spacing per point.
    m : float, optional
        Diffusion-time constant, ``t = m h^2``.
    solver : {"auto", "cg", "bicgstab", "direct"}, optional
        ``"cg"`` needs a symmetric ``H`` (global spacing); ``"bicgstab"``
        takes the non-symmetric ``H`` of the local spacing; ``"direct"`` is
        ``scipy.sparse.linalg.spsolve`` (exact, slow beyond ~1e5 points).
        ``"auto"`` picks ``"cg"`` when all ``h_i`` are equal, else ``"bicgstab"``.
    rtol : float, optional
        Relative residual the iterative solvers stop at.
    maxiter : int, optional
        Iteration cap of the iterative solvers.
    return_info : bool, optional
        Also return an :class:`AreaSolve` record.

    Returns
    -------
    areas : ndarray, shape (n,)
        ``A_i``; their sum estimates the surface area. Not guaranteed
        positive: on irregular samples the system is ill-conditioned.
    info : AreaSolve
        Only with ``return_info=True``.
    """
    H = area_matrix(nbhd, weights, h, m)
    n = nbhd.n_points
    b = np.ones(n)
    symmetric = bool(np.all(h == h[0]))
    if solver == "auto":
        solver = "cg" if symmetric else "bicgstab"
    if solver == "cg" and not symmetric:
        raise HeatcurvError("solver='cg' needs the symmetric H of the global spacing; use 'bicgstab' or 'direct'")
    # Shepard start: each point's area as if its neighbours had the same area.
    x0 = 1.0 / np.asarray(H.sum(axis=1)).ravel()
    iterations = 0

    def count(_):
        nonlocal iterations
        iterations += 1

    if solver == "cg":
        areas, _ = spla.cg(H, b, x0=x0, rtol=rtol, atol=0.0, maxiter=maxiter, callback=count)
    elif solver == "bicgstab":
        areas, _ = spla.bicgstab(H, b, x0=x0, rtol=rtol, atol=0.0, maxiter=maxiter, callback=count)
    elif solver == "direct":
        areas = spla.spsolve(H.tocsc(), b)
    else:
        raise HeatcurvError(f"unknown area solver {solver!r}; use 'auto', 'cg', 'bicgstab' or 'direct'")
    residual = float(np.linalg.norm(H @ areas - b) / np.sqrt(n))
    if not np.all(np.isfinite(areas)):
        raise HeatcurvError(f"the area system H A = 1 could not be solved ({solver} gave non-finite areas)")
    converged = residual <= max(rtol, 1e-12) * 10
    info = AreaSolve(solver=solver, iterations=iterations, residual=residual, converged=converged)
    return (areas, info) if return_info else areas


def _taper_moments(u0: float = TAPER_START) -> tuple[float, float]:
    """``I1 = int W dA`` and ``I2 = int W^2 dA`` over the unit disc, by Gauss-Legendre quadrature."""
    x, w = np.polynomial.legendre.leggauss(64)
    # the profile is smooth on [0, u0] and [u0, 1]: integrate the pieces separately
    total1 = total2 = 0.0
    for a, b in ((0.0, u0), (u0, 1.0)):
        u = 0.5 * (b - a) * x + 0.5 * (a + b)
        f = flat_top(u, u0)
        total1 += 0.5 * (b - a) * np.sum(w * f * 2 * np.pi * u)
        total2 += 0.5 * (b - a) * np.sum(w * f * f * 2 * np.pi * u)
    return float(total1), float(total2)


def density_areas(nbhd: Neighbourhood, fraction: float = 1.0) -> np.ndarray:
    """Per-point areas from a flat-top kernel density estimate, no linear solve.

    With ``R_i`` the ball radius of point ``i`` and ``W`` a flat-top profile
    (1 up to ``0.7 R``, a raised cosine to 0 at ``R``),

        A_i = I_W R_i^2 / (sum_{j != i} W(|xi - xj| / R_i) + beta),

    ``I_W = int W dA`` over the unit disc. The ``beta`` term is the point
    itself, and what it must be depends on how regular the sampling is: on a
    lattice, the kernel sum *with* the point itself is the quadrature of
    ``rho I_W R^2`` (``beta = 1``); on random (Poisson) points the sum without
    it is unbiased, and Jensen's inequality, ``E[1/(beta + S)] ~ (1/mu)(1 +
    (q - beta)/mu)`` with ``q = int W^2 / int W``, asks for ``beta = q``. A
    flat-top kernel has ``q = 0.91`` (a Gaussian has 1/2), so the midpoint
    ``beta = (1 + q)/2`` leaves at most ``(1 - q)/(2 mu)``, about 0.1 % with
    60 neighbours in the ball, for any sampling between the two.

    On spheres with 60 neighbours the total area is within half a per cent
    for random, Fibonacci and jittered samples (docs/how_it_works.md,
    thresholds). On other
    surfaces the ball's cut is larger than ``pi R^2``; multiply by
    :func:`ball_area_factor` once the principal curvatures are known.

    Parameters
    ----------
    nbhd : Neighbourhood
        Ball neighbourhoods; ``nbhd.radius`` is ``R_i``.
    fraction : float, optional
        Share of the cloud the neighbours were drawn from (a thinned
        level holding ``fraction`` of the points stands for all of them).

    Returns
    -------
    ndarray, shape (n,)
        Positive areas; their sum estimates the surface area.
    """
    radius = nbhd.radius
    total = taper_sums(nbhd) / fraction
    i1, i2 = _taper_moments()
    beta = 0.5 * (1.0 + i2 / i1)
    return i1 * radius**2 / (total + beta)


def taper_sums(nbhd: Neighbourhood) -> np.ndarray:
    """``sum_{j != i} flat_top(|xi - xj| / R_i)`` per point, shape ``(n,)``: the kernel count of each ball."""
    return kernels.taper_sums(nbhd.indptr, nbhd.distances, nbhd.radius, TAPER_START)


def cut_ball_coverage(offset: np.ndarray, threshold: float) -> np.ndarray:
    """Share of a border point's ball that the surface covers, from the ball's centroid offset.

    A ball cut by a straight border at distance ``a R`` from its centre
    (the surface on the side ``x <= a R``) holds the share

        f(a) = int_{x <= a} W dA / int W dA

    of the flat-top kernel's mass ``W`` (:func:`heatcurv.operators.kernel.flat_top`),
    and its neighbours' centroid lies ``c(a) = |int_{x <= a} W x dA| /
    int_{x <= a} W dA`` (in ball radii) off the centre: ``c = 0.37``,
    ``f = 1/2`` on the border itself. Inverting ``c(a)`` gives ``f`` from the
    measured offset. A density estimate counts the points of the covered part
    only, so a border point's area is ``f`` times what
    :func:`density_areas` gives (measured on a face range scan: the border
    band's areas were 3.1 times the mesh's, 1.7 after the correction). Below
    ``threshold`` (interior points, whose offset is sampling noise) the
    coverage is 1.

    Parameters
    ----------
    offset : ndarray, shape (n,)
        Tangential centroid offset in ball radii
        (:func:`heatcurv.flags.border.centroid_offset`).
    threshold : float
        Offset from which a ball counts as cut (``TUNING.border_offset``).

    Returns
    -------
    ndarray, shape (n,)
        Coverage in (0, 1].
    """
    c_table, f_table = _cut_disc_table()
    coverage = np.interp(offset, c_table, f_table)
    return np.where(offset > threshold, coverage, 1.0)


@functools.cache
def _cut_disc_table(u0: float = TAPER_START) -> tuple[np.ndarray, np.ndarray]:
    """``(c(a), f(a))`` of a unit disc cut at ``x = a`` for ``a`` from 1 down to -0.95, by quadrature."""
    x, wx = np.polynomial.legendre.leggauss(160)
    y, wy = np.polynomial.legendre.leggauss(48)
    # chord mass g(x) = int W(sqrt(x^2 + y^2)) dy over the disc's chord at x
    half = np.sqrt(1.0 - x**2)
    chord = (flat_top(np.hypot(x[:, None], half[:, None] * y[None, :]), u0) * wy).sum(axis=1) * half
    # cumulative mass and first moment from x = -1 up to each cut a, on the Gauss nodes
    order = np.argsort(x)
    mass = np.cumsum((chord * wx)[order])
    moment = np.cumsum((x * chord * wx)[order])
    keep = x[order] > -0.95
    c = np.abs(moment[keep]) / mass[keep]
    f = mass[keep] / mass[-1]
    return np.concatenate([[0.0], c[::-1]]), np.concatenate([[1.0], f[::-1]])




def ball_area_factor(radius: np.ndarray, k1: np.ndarray, k2: np.ndarray) -> np.ndarray:
    """How much surface a ball of chord radius ``R`` cuts, relative to ``pi R^2``.

    For the surface ``z = (k1 x^2 + k2 y^2)/2`` the ball ``r^2 + z^2 <= R^2``
    shrinks the disc by ``R^2 <kN^2> / 4`` (``<kN^2> = (3 k1^2 + 2 k1 k2 +
    3 k2^2)/8``, the mean squared normal curvature) while the area element
    grows by ``R^2 (k1^2 + k2^2) / 8``; together

        area / (pi R^2) = 1 + R^2 (k1 - k2)^2 / 32 + O(R^4),

    exactly 1 on a sphere. A density estimate over the ball counts the points
    of that larger area, so its per-point area is low by this factor.

    The expansion holds while ``R |k1 - k2|`` is small; the factor is capped
    at ``TUNING.ball_area_factor_max`` (``R |k1 - k2| = 4``), beyond which the ball
    is no patch of a surface of that curvature and the fitted curvatures of
    such a point are not trustworthy anyway (measured on a face range scan:
    uncapped, stray points reached factors of 100 and areas of 30,000 mm^2).

    Parameters
    ----------
    radius : ndarray, shape (n,)
        Ball radius ``R``.
    k1, k2 : ndarray, shape (n,)
        Principal curvatures.

    Returns
    -------
    ndarray, shape (n,)
    """
    return np.minimum(1.0 + radius**2 * (k1 - k2) ** 2 / 32.0, TUNING.ball_area_factor_max)
