"""An accurate point-cloud Laplace-Beltrami operator for any sampling (the default of :func:`heatcurv.laplacian`).

The paper's operator (eq 2.9, ``method="paper"`` of :func:`heatcurv.laplacian`)
needs per-point areas from the solve ``H A = 1`` (section 2.2), which is
unstable on irregular samples. This module builds a heat-kernel operator in
weak form instead: a mass (per-point areas) and a symmetric stiffness, the
discrete Dirichlet energy ``E(f) = 1/2 sum_ij W_ij (f_i - f_j)^2`` of the
Gaussian kernel of eq 2.8. Four steps:

1. **Areas.** ``A_i`` is the area of point ``i``'s Voronoi cell among its
   30 nearest neighbours, mapped to its tangent plane (PCA normal; each
   neighbour in its projected direction at its distance). The cells tile
   the surface, so the areas are a quadrature of it without the Monte Carlo
   noise of a density estimate (random points: sums -0.06 % on a 10 000
   point unit sphere, -0.13 % on a 5000 point torus). An *open* cell (a
   border point: a cell vertex farther than 0.8 times the distance to the
   30th neighbour) is closed by a line ``0.2`` local spacings beyond the
   point, normal to the direction in which the cell opens (the mean of its
   far vertices); the local spacing is the square root of the neighbours'
   mean closed cell. Where a border lies is not in the points: a lattice
   with a row on the border wants 0, cell-centred samples 0.5, random
   samples about 0.2 (area sums on 4000 point squares: -0.3 .. 0.0 %
   random, +0.85 .. +0.93 % jittered, +0.06 .. +0.10 % scanned).
2. **Kernel.** One global width: ``R`` is the 95th percentile of the points'
   distances to their ``neighbours``-th nearest neighbour (the ball radius):
   the sparse parts of a cloud must keep enough neighbours, as too few bias
   every eigenvalue low (10 000 point sphere of density 10:1, mean error
   0.60 % with the 95th percentile, 1.10 % with the 90th, 2.22 % with the
   80th; the dense parts pay with more pairs). The kernel is
   ``k(d) = exp(-d^2 / h^2)`` (eq 2.8, ``t = h^2/4``) with
   ``h = width * R``, cut at ``R``; the point itself is excluded. The pair weights are the
   quadrature of the continuous energy ``1/2 int int k (f(x) - f(y))^2``:
   ``w_ij = A_i A_j k(|x_i - x_j|)``.
3. **Calibration** (a symmetric scaling). ``W_ij = c_i c_j w_ij`` with
   ``c > 0`` solving ``sum_j W_ij |x_i - x_j|^2 / 4 = A_i`` at every point:
   ``L = diag(1/A) (diag(W 1) - W)`` is then exact on ``|x - x_i|^2`` at
   ``x_i`` (``L |x - x_i|^2 = -4``), so the energy of every linear function
   is exact point by point on any sampling and density. At a **border** the
   ball is cut: the second moment that matters there is the one *along*
   the border (a Neumann eigenfunction has no normal derivative), and an
   isotropic calibration overweights it (the jittered square's eigenvalues
   +1.05 % against +0.02 %). So a row whose kernel-weighted tangential
   centroid offset ``|sum_j w_ij P_i d_ij| / (h sum_j w_ij)`` exceeds 0.1
   (0.56 on a straight border) calibrates ``2 (d . v_i)^2`` instead of
   ``|d|^2``, fully from 0.3 on (``v_i`` the tangent normal to the offset).
   ``c`` comes from the fixed-point iteration ``c <- sqrt(c A / (M c))``
   (about 60 sparse products to 1e-9).
4. **Second-order correction** (``order=2``). The kernel's symbol is
   ``1 - c2 lam + c4 lam^2 + ...`` (moments of the cut Gaussian), so ``L1``
   underestimates an eigenvalue ``lam`` by about ``(c4/c2) h^2 lam^2``; the
   default returns ``L = L1 + gamma L1^2`` with ``gamma = (c4/c2) h^2``,
   which has the same eigenvectors as ``L1`` and removes that bias.

The stiffness ``S = diag(A) L = S1 + gamma S1 diag(1/A) S1`` with
``S1 = diag(W 1) - W`` (a graph Laplacian with positive weights) is
symmetric positive semi-definite, ``L 1 = 0``, and the areas are the mass.

Sign convention as in :mod:`heatcurv.operators.laplace_beltrami`: ``L`` is the
*positive* operator, ``L = -Delta``; on a sphere of radius ``R`` the
spherical harmonics of degree ``l`` have eigenvalue ``l (l + 1) / R^2`` and
``L x = 2 kappa_M n`` (eq 2.10) with outward ``n`` and ``kappa_M = 1/R``.

On an open surface the operator is the Neumann (free-border) Laplacian: the
energy has no term across the border, the weak form of a zero normal
derivative.

:class:`PointCloudLaplacian` holds the operator for repeated use: its
eigenpairs (shift-invert Lanczos on the generalised problem
``S v = lam diag(A) v``) and heat diffusion ``u_t = Delta u`` (backward
Euler with one cached factorisation).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

try:  # CHOLMOD's Cholesky through cvxopt, a dependency where it has wheels (pyproject.toml); SuperLU elsewhere
    from cvxopt import cholmod
    from cvxopt import matrix as cvxopt_matrix
    from cvxopt import spmatrix as cvxopt_spmatrix
except ImportError:
    cholmod = None

from .._kernels import laplacian as lap_kernels
from .._kernels import segment as segment_kernels
from ..errors import HeatcurvError
from ..geometry.neighbourhood import ball_neighbourhood, block_ranges, rows_per_block
from ..geometry.validation import prepare_points
from ..options import workers_problem
from .geodesic import HeatGeodesics
from .operator import build_operator

__all__ = [
    "PointCloudLaplacian", "laplacian", "point_cloud_laplacian", "kernel_moments", "spd_factor", "DEFAULT_NEIGHBOURS",
    "DEFAULT_WIDTH",
]

#: Neighbours whose distance (95th percentile) sets the ball radius ``R``.
DEFAULT_NEIGHBOURS = 60
#: Kernel width ``h`` in ball radii.
DEFAULT_WIDTH = 0.5
#: Quantile of the points' neighbour distances that sets the ball radius ``R``.
RADIUS_QUANTILE = 0.95
#: Nearest neighbours among which each point's tangent-plane Voronoi cell is cut.
VORONOI_NEIGHBOURS = 30
#: A Voronoi cell with a vertex farther than this many ``d_k`` (the distance to the last of the
#: ``VORONOI_NEIGHBOURS``) is open: its point is on a border (1.0 left cells reaching outside the
#: squares of the benchmark closed: areas +1.4 % on a 4000 point jittered square, 0.8 +0.9 %)
VORONOI_REACH = 0.8
#: An open Voronoi cell (a border point) ends this many local spacings beyond its point.
BORDER_GAP = 0.2
#: Kernel-weighted centroid offsets (in kernel widths ``h``) over which a row's calibration turns from
#: isotropic (``|d|^2``) to along the border (``2 (d . v)^2``); a straight border through the point has 0.56.
BORDER_RAMP = (0.1, 0.3)
#: Relative residual at which the symmetric scaling of the kernel weights stops, and its iteration cap.
SCALING_TOLERANCE = 1e-9
SCALING_ITERATIONS = 500


@functools.cache
def kernel_moments(width: float) -> tuple[float, float, float]:
    """Moments of the Gaussian ``exp(-r^2)`` cut at ``r = 1/width`` (``h = 1``), over the plane.

    Parameters
    ----------
    width : float
        Kernel width in ball radii (the cut is at ``1/width`` kernel widths).

    Returns
    -------
    m0 : float
        ``int W dA``.
    c2 : float
        ``<r^2>/4``: the symbol is ``1 - c2 |xi|^2 + c4 |xi|^4 - ...``.
    c4 : float
        ``<r^4>/64``.
    """
    cut = 1.0 / width
    x, w = np.polynomial.legendre.leggauss(96)
    r = 0.5 * cut * (x + 1.0)
    w = 0.5 * cut * w * np.exp(-r * r) * 2.0 * np.pi * r
    m0 = float(np.sum(w))
    return m0, float(np.sum(w * r**2) / m0 / 4.0), float(np.sum(w * r**4) / m0 / 64.0)


def _check_options(neighbours, width, order) -> tuple[int, float, int]:
    if isinstance(neighbours, bool) or not isinstance(neighbours, (int, np.integer)) or neighbours < 8:
        raise HeatcurvError(f"neighbours must be an integer >= 8, got {neighbours!r}")
    try:
        width = float(width)
    except (TypeError, ValueError):
        raise HeatcurvError(f"width must be a number in [0.25, 1], got {width!r}") from None
    if not 0.25 <= width <= 1.0:
        raise HeatcurvError(f"width must be a number in [0.25, 1] (kernel width in ball radii), got {width!r}")
    if order not in (1, 2) or isinstance(order, bool):
        raise HeatcurvError(f"order must be 1 or 2, got {order!r}")
    return int(neighbours), width, int(order)


def _voronoi_areas(X: np.ndarray, tree: cKDTree, neighbours: int, gap: float, workers: int):
    """Tangent-plane Voronoi areas ``(n,)``, PCA normals ``(n, 3)`` and open-cell flags ``(n,)`` of distinct ``X``."""
    n = X.shape[0]
    k = min(neighbours, n - 1)
    dist, nbr = tree.query(X, k + 1, workers=workers)
    nbr = np.ascontiguousarray(nbr[:, 1:])
    normals, _ = segment_kernels.smallest_eigenvectors(lap_kernels.knn_covariances(X, nbr))
    area, opened = lap_kernels.voronoi_cells(X, nbr, normals, np.zeros(n), VORONOI_REACH)
    if np.any(opened) and gap > 0:
        # an open cell (a border point) ends `gap` local spacings beyond its point; the local spacing is
        # the square root of the mean closed cell among its neighbours
        closed = np.where(opened, 0.0, area)
        rows = np.flatnonzero(opened)
        count = (~opened)[nbr[rows]].sum(axis=1)
        if np.any(~opened):
            fallback = float(np.median(area[~opened]))
        else:  # no closed cell at all (a strip a few points wide): the nearest-neighbour spacing
            fallback = float(np.median(dist[:, 1])) ** 2
        local = np.where(count > 0, closed[nbr[rows]].sum(axis=1) / np.maximum(count, 1), fallback)
        spacing = np.zeros(n)
        spacing[rows] = gap * np.sqrt(local)
        area, _ = lap_kernels.voronoi_cells(X, nbr, normals, spacing, VORONOI_REACH)
    if not np.all(area > 0):
        raise HeatcurvError("a point has a Voronoi cell of zero area: the cloud has (nearly) coincident points")
    return area, normals, opened


def _symmetric_scaling(M: sp.csr_matrix, target: np.ndarray) -> np.ndarray:
    """``c > 0`` with ``c_i sum_j M_ij c_j = target_i`` (the geometric-mean fixed-point iteration)."""
    c = np.full(target.size, np.sqrt(target.sum() / M.sum()))
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        for _ in range(SCALING_ITERATIONS):
            Mc = M @ c
            residual = float(np.max(np.abs(c * Mc / target - 1.0)))
            if residual < SCALING_TOLERANCE or not np.isfinite(residual):
                break
            c = np.sqrt(c * target / Mc)
    if residual < SCALING_TOLERANCE:
        return c
    if not residual <= 1e-6:  # also NaN: weights that underflow around isolated points overflow c
        raise HeatcurvError(
            f"the calibration of the kernel weights did not converge (relative residual {residual:.1e} after "
            f"{SCALING_ITERATIONS} iterations): is the cloud a sampled surface, without isolated outliers?"
        )
    return c


def _scale_pairs(W: sp.csr_matrix, factor: np.ndarray) -> None:
    """``W_ij *= factor_i factor_j`` in place, a block of rows at a time (bounded temporaries)."""
    for lo, hi in block_ranges(W.shape[0], rows_per_block(W.nnz // W.shape[0])):
        a, b = W.indptr[lo], W.indptr[hi]
        rows = np.repeat(np.arange(lo, hi), np.diff(W.indptr[lo : hi + 1]))
        W.data[a:b] *= factor[rows] * factor[W.indices[a:b]]


def _stiffness_and_areas(X: np.ndarray, tree: cKDTree, neighbours: int, width: float, order: int, workers: int):
    """Stiffness ``S`` (CSR, symmetric), areas ``A``, ``h``, ``R`` and ``gamma`` of distinct, centred points ``X``."""
    n = X.shape[0]
    kth, _ = tree.query(X, [neighbours], workers=workers)
    R = float(np.quantile(kth, RADIUS_QUANTILE))
    if not R > 0:
        raise HeatcurvError("the neighbour distances are zero: too many coincident points")
    h = width * R
    area, normals, _ = _voronoi_areas(X, tree, VORONOI_NEIGHBOURS, BORDER_GAP, workers)
    nbhd = ball_neighbourhood(X, R, tree=tree, min_neighbours=8, workers=workers)
    # pairs of points given their nearest neighbours beyond R (sparse parts) are made symmetric here
    K = sp.csr_matrix((np.exp(-((nbhd.distances / h) ** 2)), nbhd.indices, nbhd.indptr), shape=(n, n))
    del nbhd
    K = K.maximum(K.T).tocsr()
    # the quadrature of the kernel energy: w_ij = A_i A_j k(|xi - xj|) (scaled in place: no sparse products)
    W = K
    W.sort_indices()
    _scale_pairs(W, area)
    moment, total = lap_kernels.border_moments(X, W.indptr, W.indices, W.data, normals)
    if not np.all(total > 0):
        raise HeatcurvError("a point has no neighbour within its kernel: the cloud has isolated points")
    size = np.linalg.norm(moment, axis=1)
    offset = size / (total * h)  # a straight border through the point: 1/sqrt(pi) = 0.56
    lo, hi = BORDER_RAMP
    beta = np.clip((offset - lo) / (hi - lo), 0.0, 1.0)
    along = np.cross(normals, moment / np.where(size > 0, size, 1.0)[:, None])
    beta[size == 0] = 0.0
    M = sp.csr_matrix((lap_kernels.moment_weights(X, W.indptr, W.indices, W.data, beta, along), W.indices, W.indptr),
                      shape=(n, n))
    c = _symmetric_scaling(M, area)
    del M
    _scale_pairs(W, c)
    S = (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()
    _, c2, c4 = kernel_moments(width)
    gamma = c4 / c2 * h * h if order == 2 else 0.0
    return S, area, h, R, gamma


def point_cloud_laplacian(
    points, neighbours: int = DEFAULT_NEIGHBOURS, width: float = DEFAULT_WIDTH, order: int = 2, workers: int = -1
) -> tuple[sp.csr_matrix, np.ndarray]:
    """The accurate point-cloud Laplace-Beltrami matrix and per-point areas (module docstring).

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Distinct point coordinates.
    neighbours : int, optional
        The ball radius ``R`` is the 95th percentile of the distances to this
        many nearest neighbours (default 60).
    width : float, optional
        Kernel width ``h = width * R``, in [0.25, 1] (default 0.5).
    order : {1, 2}, optional
        2 (default) adds the second-order symbol correction (denser matrix:
        about 3.5 times the pairs); 1 is the plain calibrated operator.
    workers : int, optional
        Threads for the k-d tree queries (the numba kernels use
        :func:`heatcurv.backend.threads`).

    Returns
    -------
    L : scipy.sparse.csr_matrix, shape (n, n)
        The positive operator ``-Delta`` (``L @ 1 = 0``), rows in input order,
        units 1/length^2.
    area : ndarray, shape (n,)
        Positive per-point areas; ``diag(area) @ L`` is symmetric positive
        semi-definite.

    Raises
    ------
    HeatcurvError
        On bad input (non-finite values, wrong shape, too few points), exact
        duplicates, and bad option values.
    """
    lap = PointCloudLaplacian(points, neighbours=neighbours, width=width, order=order, workers=workers)
    return lap.matrix, lap.area


@dataclass
class PointCloudLaplacian:
    """A precompute-once Laplace-Beltrami operator of a point cloud, for repeated queries.

    In the style of potpourri3d's solvers: build it once, then ask for the
    operator, the areas, the first eigenpairs and heat diffusion. Every
    array is in input order and input units.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Distinct point coordinates.
    neighbours, width, order, workers
        As in :func:`point_cloud_laplacian`. ``workers`` bounds the build's
        threads, not those of the sparse factorisations of :meth:`eigenpairs`,
        :meth:`heat` and :meth:`geodesic_distance` (CHOLMOD through cvxopt,
        with the threads of its own BLAS).

    Attributes
    ----------
    first_order : scipy.sparse.csr_matrix, shape (n, n)
        ``S1 = diag(area) L1``, the stiffness of the first-order operator:
        symmetric positive semi-definite, rows summing to 0, about
        ``neighbours`` pairs a row.
    gamma : float
        Second-order coefficient, length^2 (0 for ``order=1``):
        ``L = L1 + gamma L1^2``.
    area : ndarray, shape (n,)
        Per-point areas (the lumped mass).
    h : float
        Kernel width, input units.
    radius : float
        Ball radius ``R``, input units.

    Examples
    --------
    >>> import numpy as np, heatcurv
    >>> pts = heatcurv.surfaces.Sphere().sample(3000, "random", seed=0).points
    >>> lap = heatcurv.PointCloudLaplacian(pts)
    >>> values, vectors = lap.eigenpairs(4)
    >>> bool(np.allclose(values[1:], 2.0, rtol=0.03))
    True
    """

    points: np.ndarray
    neighbours: int = DEFAULT_NEIGHBOURS
    width: float = DEFAULT_WIDTH
    order: int = 2
    workers: int = -1
    first_order: sp.csr_matrix = field(init=False, repr=False)
    gamma: float = field(init=False)
    area: np.ndarray = field(init=False, repr=False)
    h: float = field(init=False)
    radius: float = field(init=False)
    _eigen: tuple | None = field(default=None, init=False, repr=False)
    _heat: dict = field(default_factory=dict, init=False, repr=False)
    _stiffness: sp.csr_matrix | None = field(default=None, init=False, repr=False)
    _geodesics: HeatGeodesics | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        self.neighbours, self.width, self.order = _check_options(self.neighbours, self.width, self.order)
        problem = workers_problem(self.workers)
        if problem:
            raise HeatcurvError(problem)
        prepared = prepare_points(self.points, min_points=self.neighbours + 1)
        if prepared.n_distinct != prepared.n_input:
            raise HeatcurvError(
                f"points hold {prepared.n_input - prepared.n_distinct} exact duplicate(s); "
                "a Laplacian needs one row per distinct point: remove duplicates first"
            )
        self.points = np.asarray(self.points, dtype=np.float64)
        X = prepared.points  # distinct, centred, in input order (no reordering here)
        tree = cKDTree(X)
        S, area, h, R, gamma = _stiffness_and_areas(X, tree, self.neighbours, self.width, self.order, self.workers)
        unit = prepared.unit
        perm = prepared.inverse
        if not np.array_equal(perm, np.arange(perm.size)):
            S, area = S[perm][:, perm].tocsr(), area[perm]
        self.first_order = S  # S1 = diag(A) L1: length^2 * length^-2, unit-free
        self.area = area * unit**2
        self.h, self.radius, self.gamma = h * unit, R * unit, gamma * unit**2

    @property
    def n(self) -> int:
        """Number of points."""
        return self.area.size

    @property
    def stiffness(self) -> sp.csr_matrix:
        """``S = diag(area) L = S1 + gamma S1 diag(1/area) S1``, shape ``(n, n)``: symmetric PSD, rows sum to 0.

        Assembled on first use (about 3.5 times the pairs of ``S1`` for ``order=2``).
        """
        if self._stiffness is None:
            S = self.first_order
            if self.gamma > 0:
                S = S + self.gamma * (S @ sp.diags(1.0 / self.area) @ S)
                S = (0.5 * (S + S.T)).tocsr()
            self._stiffness = S
        return self._stiffness

    @property
    def matrix(self) -> sp.csr_matrix:
        """``L = diag(1/area) S``, shape ``(n, n)``: the positive operator ``-Delta``."""
        return (sp.diags(1.0 / self.area) @ self.stiffness).tocsr()

    @property
    def mass(self) -> sp.dia_matrix:
        """``diag(area)``, shape ``(n, n)``."""
        return sp.diags(self.area)

    def apply(self, values) -> np.ndarray:
        """``L f`` for a field ``f`` of shape ``(n,)`` or ``(n, c)``."""
        values = np.asarray(values, dtype=np.float64)
        if values.shape[:1] != (self.n,):
            raise HeatcurvError(f"the field has shape {values.shape}, the cloud {self.n} points")
        weight = self.area if values.ndim == 1 else self.area[:, None]
        out = (self.first_order @ values) / weight
        if self.gamma > 0:
            out = out + self.gamma * (self.first_order @ out) / weight
        return out

    def mean_curvature_normal(self) -> np.ndarray:
        """``K = L x`` (eq 2.10), shape ``(n, 3)``: ``2 kappa_M n`` in heatcurv's sign convention."""
        return self.apply(self.points - self.points.mean(axis=0))

    def eigenpairs(self, k: int = 10) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` smallest eigenpairs of ``S v = lam diag(area) v``.

        Shift-invert Lanczos (:func:`scipy.sparse.linalg.eigsh`) about a small
        negative shift, on the sparser first-order stiffness ``S1``: ``L`` is
        the polynomial ``L1 + gamma L1^2`` of ``L1``, so it has the same
        eigenvectors and the eigenvalues ``mu + gamma mu^2``. Results are
        cached and reused for any smaller ``k``.

        Parameters
        ----------
        k : int
            Number of eigenpairs, ``1 <= k < n``.

        Returns
        -------
        values : ndarray, shape (k,)
            Ascending eigenvalues (the first is 0 up to rounding), 1/length^2.
        vectors : ndarray, shape (n, k)
            Eigenvectors, orthonormal in the mass inner product
            (``V.T @ diag(area) @ V = I``).
        """
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k < self.n - 1:
            raise HeatcurvError(f"k must be an integer in [1, {self.n - 2}], got {k!r}")
        if self._eigen is None or self._eigen[0].size < k:
            mass = self.mass.tocsc()
            S1 = self.first_order
            sigma = -1e-3 * float(np.median(S1.diagonal() / self.area))
            lu = spd_factor(S1 - sigma * mass)
            op = spla.LinearOperator(S1.shape, matvec=lu.solve, dtype=np.float64)
            mu, vectors = spla.eigsh(S1, k=k, M=mass, sigma=sigma, OPinv=op, which="LM")
            order = np.argsort(mu)
            mu = np.maximum(mu[order], 0.0)
            self._eigen = (mu + self.gamma * mu**2, vectors[:, order])
        values, vectors = self._eigen
        return values[:k].copy(), vectors[:, :k].copy()

    def heat(self, values, time: float, steps: int = 1) -> np.ndarray:
        """Diffuse a field by the heat equation ``u_t = Delta u`` for ``time``.

        Backward Euler, ``(diag(A) + tau S) u_{k+1} = diag(A) u_k`` with
        ``tau = time / steps``; the factorisation is cached per ``tau``.
        Unconditionally stable, and it keeps ``sum_i A_i u_i`` (the total
        heat) exactly. The matrix is never assembled: with
        ``S = S1 + gamma S1 diag(1/A) S1`` it is the product
        ``(diag(A) + a S1) diag(1/A) (diag(A) + b S1)``, ``a + b = tau``,
        ``a b = tau gamma``, so each step solves with the sparse first-order
        stiffness (:meth:`_backward_euler`).

        Parameters
        ----------
        values : array_like, shape (n,) or (n, c)
            Initial field(s).
        time : float
            Diffusion time, length^2 (heat spreads over about ``sqrt(4 time)``).
        steps : int, optional
            Backward Euler steps.

        Returns
        -------
        ndarray, same shape as ``values``
        """
        u = np.asarray(values, dtype=np.float64)
        if u.shape[:1] != (self.n,) or u.ndim > 2:
            raise HeatcurvError(f"values must have shape ({self.n},) or ({self.n}, c), got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise HeatcurvError(f"values hold {np.count_nonzero(~np.isfinite(u))} NaN or infinite entries")
        try:
            time = float(time)
        except (TypeError, ValueError):
            raise HeatcurvError(f"time must be a positive number, got {time!r}") from None
        if not (np.isfinite(time) and time > 0):
            raise HeatcurvError(f"time must be a positive number, got {time!r}")
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise HeatcurvError(f"steps must be a positive integer, got {steps!r}")
        tau = time / steps
        if tau not in self._heat:
            self._heat = {tau: self._backward_euler(tau)}
        solve = self._heat[tau]
        weight = self.area if u.ndim == 1 else self.area[:, None]
        for _ in range(int(steps)):
            u = solve(weight * u)
        return u

    def geodesic_distance(self, sources) -> np.ndarray:
        """Geodesic distance from the nearest source to every point, by the heat method.

        The heat method of Crane et al. 2013 on this operator's pair weights
        (:mod:`heatcurv.operators.geodesic`): one heat step, the field's unit
        tangent gradient, and a Poisson solve. The first call factorises two
        matrices; every further call costs two solves and a few sparse
        products.

        Parameters
        ----------
        sources : int or array_like of int
            One point index or several (the distance is to the nearest).

        Returns
        -------
        ndarray, shape (n,)
            Distances in input units: 0 at the sources, ``inf`` in connected pieces of the cloud
            that hold none.

        Examples
        --------
        >>> import numpy as np, heatcurv
        >>> pts = heatcurv.surfaces.Sphere().sample(3000, "random", seed=0).points
        >>> lap = heatcurv.PointCloudLaplacian(pts)
        >>> far = int(np.argmin(pts @ pts[0]))  # the point farthest from point 0
        >>> bool(abs(lap.geodesic_distance(0)[far] - np.arccos(pts[far] @ pts[0])) < 0.05)
        True
        """
        index = np.atleast_1d(np.asarray(sources))
        if index.dtype == bool:
            raise HeatcurvError("sources must be point indices, got booleans; for a mask pass np.flatnonzero(mask)")
        if index.size == 0 or index.ndim != 1 or not np.issubdtype(index.dtype, np.integer):
            raise HeatcurvError(f"sources must be a point index or a 1-D list of them, got {sources!r}")
        if index.min() < 0 or index.max() >= self.n:
            raise HeatcurvError(f"sources must be point indices in [0, {self.n - 1}], got {sources!r}")
        if self._geodesics is None:
            self._geodesics = HeatGeodesics(self.points, self.area, self.first_order, spd_factor)
        return self._geodesics.distance(np.unique(index))

    def _backward_euler(self, tau: float):
        """A solver of ``(diag(A) + tau S) u = r``, ``r`` of shape ``(n,)`` or ``(n, c)``, from factors of ``S1``.

        ``diag(A) + tau (S1 + gamma S1 diag(1/A) S1) = (diag(A) + a S1) diag(1/A) (diag(A) + b S1)``
        with ``a, b = (tau -+ sqrt(tau^2 - 4 tau gamma)) / 2``. For ``tau >= 4 gamma`` both are
        positive: two solves with positive definite matrices in turn. For a shorter step they are
        complex conjugates, and the partial fractions
        ``1 / ((1 + a mu) (1 + b mu)) = Im(a / (1 + a mu)) / Im(a)`` (``mu`` an eigenvalue of ``L1``) give
        ``u = Im(a (diag(A) + a S1)^-1 r) / Im(a)``: one complex factorisation.
        """
        mass, S1, gamma = self.mass, self.first_order, self.gamma
        if gamma == 0.0:
            return spd_factor(mass + tau * S1).solve
        discriminant = tau * tau - 4.0 * tau * gamma
        if discriminant >= 0.0:
            root = np.sqrt(discriminant)
            first, second = spd_factor(mass + 0.5 * (tau - root) * S1), spd_factor(mass + 0.5 * (tau + root) * S1)

            def solve(r):
                return second.solve((self.area if r.ndim == 1 else self.area[:, None]) * first.solve(r))

            return solve
        a = complex(0.5 * tau, 0.5 * np.sqrt(-discriminant))
        # complex symmetric with a positive definite real part: no pivoting needed either
        lu = spd_factor(mass.astype(complex) + a * S1)

        def solve(r):
            return (a * lu.solve(r.astype(complex))).imag / a.imag

        return solve


class CholeskyFactor:
    """CHOLMOD's supernodal Cholesky factor of a real symmetric positive definite matrix (cvxopt).

    It stores ``L`` alone where an LU stores ``L`` and ``U``; with the
    optimised BLAS cvxopt ships it factorises and solves these stiffness
    matrices in about a third of SuperLU's time (docs/laplacian.md).
    ``solve(b)`` takes ``b`` of shape ``(n,)`` or ``(n, c)``.
    """

    def __init__(self, matrix: sp.spmatrix):
        lower = sp.tril(matrix, format="coo")  # CHOLMOD reads the lower triangle
        stiffness = cvxopt_spmatrix(cvxopt_matrix(lower.data.astype(np.float64)),
                                    cvxopt_matrix(lower.row.astype(np.int64)),
                                    cvxopt_matrix(lower.col.astype(np.int64)), matrix.shape)
        self._factor = cholmod.symbolic(stiffness)
        try:
            cholmod.numeric(stiffness, self._factor)
        except ArithmeticError as err:  # CHOLMOD met a pivot <= 0, in the column it names
            raise HeatcurvError(f"a matrix to factorise is not positive definite (pivot {err}): is the cloud "
                                "a sampled surface, without coincident or isolated points?") from None

    def solve(self, b) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        x = cvxopt_matrix(b)  # a copy, which CHOLMOD overwrites with the solution
        cholmod.solve(self._factor, x)
        return np.array(x).reshape(b.shape)


def spd_factor(matrix: sp.spmatrix):
    """A sparse factorisation of a symmetric positive definite matrix, ``f.solve(b)`` solving ``matrix x = b``.

    A real matrix gets a Cholesky factor (:class:`CholeskyFactor`) where
    cvxopt is installed (a dependency on the platforms it has wheels for);
    a complex symmetric one whose real part is positive definite (the short
    heat steps of :class:`PointCloudLaplacian`), or any matrix without
    cvxopt, SuperLU's LU with the minimum-degree ordering of ``A + A^T`` and
    no row pivoting (``diag_pivot_thresh=0``, symmetric mode): a positive
    definite matrix needs none, and SuperLU's default threshold pivoting
    departs from the symmetric ordering, which makes the factorisation of
    these stiffness matrices many times slower for the same fill
    (docs/laplacian.md). The two solve to rounding alike.

    Parameters
    ----------
    matrix : scipy.sparse matrix, shape (n, n)
        Symmetric positive definite.

    Returns
    -------
    CholeskyFactor or scipy.sparse.linalg.SuperLU
    """
    if cholmod is not None and not np.iscomplexobj(matrix.data):
        return CholeskyFactor(matrix)
    return spla.splu(sp.csc_matrix(matrix), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def laplacian(points, method: str = "default", **options):
    """The Laplace-Beltrami matrix and per-point areas of a point cloud.

    ``method="default"`` is the accurate operator of
    :mod:`heatcurv.operators.point_laplacian`: the heat kernel's energy over
    tangent-plane Voronoi areas, calibrated point by point (along the border
    at a border) and corrected to second order, accurate on any sampling
    (10 000 random points on the unit sphere: eigenvalues of degrees 1-5
    within 0.3 % on average, Fibonacci 0.1 %; docs/laplacian.md).
    ``diag(area) @ L`` is symmetric positive semi-definite, ``L @ 1 = 0``.

    ``method="paper"`` is the literal operator of eqs 2.4 and 2.9 (eq 2.6
    spacing, alpha = 4, m = 1/4, areas from ``H A = 1``) through
    :class:`HeatKernelOperator`: on a regular 8000 point sphere its residual
    on the degree-1 and degree-2 spherical harmonics is 0.7 % and 0.9 %
    (relative 2-norm); on irregular (random) samples the area system fails
    and so does the operator.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Point coordinates; must be distinct (a Laplacian row per input point).
    method : {"default", "paper"}, optional
        Which operator.
    **options
        ``"default"``: ``neighbours``, ``width``, ``order``, ``workers`` (see
        :func:`heatcurv.operators.point_laplacian.point_cloud_laplacian`).
        ``"paper"``: ``alpha``, ``m``, ``spacing``, ``gamma``, ``area_method``,
        ``area_solver`` ... as in :func:`heatcurv.estimate`.

    Returns
    -------
    L : scipy.sparse.csr_matrix, shape (n, n)
        The positive operator (``L = -Delta``), rows in input order; ``L @ f`` applies it.
    area : ndarray, shape (n,)
        Per-point areas; ``diag(area) @ L`` is the symmetric stiffness matrix
        (for ``"paper"``, with the global spacing).

    Raises
    ------
    HeatcurvError
        On bad input, unknown options, and on exact duplicate points (a
        Laplacian needs one row per distinct point; remove duplicates first).

    Examples
    --------
    >>> import numpy as np, heatcurv
    >>> pts = heatcurv.surfaces.Sphere().sample(2000, "random", seed=0).points
    >>> L, area = heatcurv.laplacian(pts)
    >>> bool(np.allclose(L @ np.ones(len(pts)), 0.0))
    True
    """
    if method != "paper":
        if method != "default":
            raise HeatcurvError(f"method must be 'default' or 'paper', got {method!r}")
        unknown = sorted(set(options) - {"neighbours", "width", "order", "workers"})
        if unknown:
            raise HeatcurvError(
                f"unknown option(s) {unknown} for laplacian(method='default'): "
                "use neighbours, width, order, workers (or method='paper' for the paper's options)"
            )
        return point_cloud_laplacian(points, **options)
    op = build_operator(points, method=method, **options)
    if op.prepared.n_distinct != op.prepared.n_input:
        raise HeatcurvError(
            f"points hold {op.prepared.n_input - op.prepared.n_distinct} exact duplicate(s); "
            "a Laplacian needs one row per distinct point: remove duplicates first"
        )
    unit = op.prepared.unit
    L = op.matrix() / unit**2 if unit != 1.0 else op.matrix()  # 1/length^2, back to input units
    # distinct points are in k-d tree order; permute back to the input order
    perm = op.prepared.inverse
    return L[perm][:, perm].tocsr(), op.areas[perm] * unit**2
