"""Analytic test surfaces with exact differential geometry, and point samplers.

Every surface here is given by a parametrisation ``X(u, v)`` with analytic first
and second derivatives, so its unit normal, principal curvatures ``k1 >= k2``,
mean and Gaussian curvature and principal directions are known exactly.  The
samplers turn a surface into a point cloud (:class:`SurfaceSample`) that
carries these exact values as ground truth for estimators, tests and benchmarks.

Sign convention
---------------
A curvature is **positive where the surface bends away from its normal**: the
normal curvature of a chord is ``2 (x_i - x_j) . n_i / |x_i - x_j|^2``.  With
``II_ab = X_ab . n`` and the first fundamental form ``I``, the shape operator is
``S = -I^{-1} II``; ``k1 >= k2`` are its eigenvalues, ``mean = (k1 + k2) / 2``
and ``gaussian = k1 * k2``.  A sphere of radius ``R`` with outward normals has
``mean = k1 = k2 = +1/R``.  The principal directions ``d1`` (for ``k1``) and
``d2`` (for ``k2``) are unit 3-D tangent vectors with ``d1 x d2 = n``
(``d2 = n x d1``).  At umbilics (``|k1 - k2| <= 1e-9 max(1, |k1|, |k2|)``) they
are some orthonormal tangent frame with the same handedness.

Normal orientation
------------------
Closed surfaces (:class:`Sphere`, :class:`Torus`): outward.  Graphs
(:class:`Graph`, :class:`Paraboloid`, :class:`Saddle`, :class:`Arch`,
:class:`Plane`) and :class:`FoldedSquare`: positive z-component.
:class:`Cylinder`: away from the axis.  Consequently an upward-opening
:class:`Paraboloid` (``a > 0``) has *negative* curvature and the
:class:`Arch` ridge has *positive* curvature.

Samplers
--------
``"grid"``
    Regular grid in parameter space, border included; periodic directions do
    not repeat the seam, and the numbers of rows and columns are chosen so
    that cells are nearly square in 3-D (``m x m`` with ``m = round(sqrt(n))``
    for the square graph domains).  On the sphere a latitude-longitude grid
    degenerates at the poles, so ``"grid"`` gives the Fibonacci sphere there.
``"fibonacci"``
    The 2-D Fibonacci lattice ``((i + 0.5) / n, frac(i * golden))`` in the
    unit square, mapped by the surface's area-preserving map where it has one
    (sphere: the classic Fibonacci sphere, torus: inverse CDF of the area
    element in the tube angle, cylinder: linear) and by the plain linear
    parameter map otherwise (graphs, plane, folded square: *not*
    area-uniform on curved graphs).  Exactly ``n`` points.
``"random"``
    Area-uniform random points, exactly ``n``, by rejection sampling in the
    parameter domain with acceptance ``|X_u x X_v| / max``.
``"jittered"``
    The grid with every point moved uniformly within +-0.25 cell in parameter
    space (reflected back at a domain border, wrapped in periodic
    directions).  On the sphere the jitter moves the
    Fibonacci points, along the east and north directions by up to
    +-0.25 cell (cell side ``sqrt(4 pi / n) R``), then projected back.

``noise > 0`` adds isotropic Gaussian noise of standard deviation
``noise * diag`` (``diag`` = bounding-box diagonal of the clean points); the
exact quantities are always those of the clean points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import Callable

import numpy as np

from heatcurv.errors import HeatcurvError

__all__ = [
    "Arch",
    "Curvature",
    "Cylinder",
    "FoldedSquare",
    "Graph",
    "Paraboloid",
    "Plane",
    "SAMPLERS",
    "SURFACES",
    "Saddle",
    "Sphere",
    "Surface",
    "SurfaceSample",
    "Torus",
    "get",
]

#: Names of the supported samplers, see :meth:`Surface.sample`.
SAMPLERS = ("grid", "fibonacci", "random", "jittered")

_GOLDEN = (1.0 + math.sqrt(5.0)) / 2.0
_UMBILIC_RTOL = 1e-9
_TWO_PI = 2.0 * math.pi


# ---------------------------------------------------------------------------
# small vectorised helpers
# ---------------------------------------------------------------------------


def _as_uv(u, v) -> tuple[np.ndarray, np.ndarray]:
    """Return ``u`` and ``v`` as equally long, finite, 1-D float64 arrays."""
    try:
        u = np.asarray(u, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise HeatcurvError(f"u and v must be numeric arrays: {exc}") from exc
    try:
        u, v = np.broadcast_arrays(u, v)
    except ValueError:
        raise HeatcurvError(
            f"u and v must have the same length, got shapes {u.shape} and {v.shape}"
        ) from None
    u = np.ascontiguousarray(u.reshape(-1))
    v = np.ascontiguousarray(v.reshape(-1))
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(v))):
        raise HeatcurvError("u and v must be finite (found NaN or inf)")
    return u, v


def _vec(n: int, x, y, z) -> np.ndarray:
    """Stack three broadcastable components into an ``(n, 3)`` float64 array."""
    out = np.empty((n, 3), dtype=np.float64)
    out[:, 0] = x
    out[:, 1] = y
    out[:, 2] = z
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.linalg.norm(a, axis=1)[:, None]


def _positive(name: str, value) -> float:
    """Validate a finite, strictly positive real parameter."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise HeatcurvError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise HeatcurvError(f"{name} must be finite and > 0, got {value!r}")
    return value


def _finite(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise HeatcurvError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise HeatcurvError(f"{name} must be finite, got {value!r}")
    return value


def _fibonacci_unit(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The 2-D Fibonacci lattice ``((i + 0.5) / n, frac(i * golden))``, i < n."""
    i = np.arange(n, dtype=np.float64)
    t1 = (i + 0.5) / n
    # frac(i * golden) == frac(i * (golden - 1)); the latter keeps more digits.
    t2 = np.mod(i * (_GOLDEN - 1.0), 1.0)
    return t1, t2


def _reflect(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Reflect values that left ``[lo, hi]`` by less than its width back inside."""
    x = np.where(x < lo, 2.0 * lo - x, x)
    x = np.where(x > hi, 2.0 * hi - x, x)
    return np.clip(x, lo, hi)


def _wrap(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Wrap values periodically into ``[lo, hi)``."""
    period = hi - lo
    y = np.mod(x - lo, period)
    y = np.where(y >= period, 0.0, y)  # np.mod(-tiny, p) can round to p
    return lo + y


# ---------------------------------------------------------------------------
# result containers
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Curvature:
    """Exact curvature quantities at ``n`` surface points.

    Attributes
    ----------
    mean : ndarray, shape (n,)
        Mean curvature ``(k1 + k2) / 2``.
    gaussian : ndarray, shape (n,)
        Gaussian curvature ``k1 * k2``.
    k1, k2 : ndarray, shape (n,)
        Principal curvatures, ``k1 >= k2``; positive where the surface bends
        away from its normal.
    d1, d2 : ndarray, shape (n, 3)
        Unit principal directions for ``k1`` and ``k2``, tangent to the
        surface, with ``d1 x d2 = n``.  Arbitrary (but still such a frame)
        where ``umbilic`` is True.
    umbilic : ndarray of bool, shape (n,)
        ``|k1 - k2| <= 1e-9 * max(1, |k1|, |k2|)``.
    """

    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    umbilic: np.ndarray


def _umbilic_mask(k1: np.ndarray, k2: np.ndarray) -> np.ndarray:
    scale = np.maximum(1.0, np.maximum(np.abs(k1), np.abs(k2)))
    return np.abs(k1 - k2) <= _UMBILIC_RTOL * scale


def _curvature_in_frame(e1, e2, b11, b12, b22) -> Curvature:
    """Diagonalise the symmetric shape operator ``[[b11, b12], [b12, b22]]``.

    ``e1``, ``e2`` (shape (n, 3)) are an orthonormal tangent frame with
    ``e1 x e2 = n`` in which the shape operator has the given entries.
    """
    # "+ 0.0" turns the -0.0 of -II on flat surfaces into +0.0.
    b11, b12, b22 = b11 + 0.0, b12 + 0.0, b22 + 0.0
    half_diff = 0.5 * (b11 - b22)
    mean = 0.5 * (b11 + b22)
    radius = np.hypot(half_diff, b12)
    k1 = mean + radius
    k2 = mean - radius
    # The quadratic form is mean + radius * cos(2 theta - psi) with
    # psi = atan2(b12, half_diff); its maximum (k1) is at theta = psi / 2.
    theta = 0.5 * np.arctan2(b12, half_diff)
    c = np.cos(theta)[:, None]
    s = np.sin(theta)[:, None]
    d1 = c * e1 + s * e2
    d2 = c * e2 - s * e1  # = n x d1
    return Curvature(
        mean=mean,
        gaussian=k1 * k2,
        k1=k1,
        k2=k2,
        d1=d1,
        d2=d2,
        umbilic=_umbilic_mask(k1, k2),
    )


@dataclass(frozen=True, eq=False)
class SurfaceSample:
    """A point cloud drawn from a :class:`Surface`, with exact ground truth.

    Attributes
    ----------
    surface : Surface
        The surface the points were drawn from.
    sampler : str
        Name of the sampler (one of :data:`SAMPLERS`, or ``"custom"`` for
        :meth:`Surface.sample_at`).
    noise : float
        Noise standard deviation as a fraction of the bounding-box diagonal of
        ``clean_points``.
    sigma : float
        The absolute noise standard deviation that was applied.
    points : ndarray, shape (n, 3)
        What an estimator sees: ``clean_points`` plus noise.
    clean_points : ndarray, shape (n, 3)
        Points exactly on the surface.
    u, v : ndarray, shape (n,)
        Parameters of the clean points.
    normals : ndarray, shape (n, 3)
        Exact unit normals at the clean points.
    mean, gaussian, k1, k2 : ndarray, shape (n,)
        Exact curvatures at the clean points (see :class:`Curvature`).
    d1, d2 : ndarray, shape (n, 3)
        Exact principal directions.
    umbilic : ndarray of bool, shape (n,)
        Where the principal directions are undefined.
    total_area : float
        Exact area of the whole surface.
    border_distance : ndarray, shape (n,)
        Lower bound on the distance along the surface to the border
        (``inf`` on closed surfaces).
    feature_distance : ndarray, shape (n,)
        Distance along the surface to the nearest sharp feature (the fold of a
        :class:`FoldedSquare`); ``inf`` on smooth surfaces.
    """

    surface: "Surface"
    sampler: str
    noise: float
    sigma: float
    points: np.ndarray
    clean_points: np.ndarray
    u: np.ndarray
    v: np.ndarray
    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    umbilic: np.ndarray
    total_area: float
    border_distance: np.ndarray
    feature_distance: np.ndarray = field(repr=False)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def n(self) -> int:
        """Number of points."""
        return len(self)

    @property
    def fold_distance(self) -> np.ndarray:
        """Alias of :attr:`feature_distance` (distance to the fold), shape (n,)."""
        return self.feature_distance

    def interior(self, margin: float) -> np.ndarray:
        """Mask of the points farther than ``margin`` from the border.

        Parameters
        ----------
        margin : float
            Distance along the surface.

        Returns
        -------
        ndarray of bool, shape (n,)
            ``border_distance > margin``; all True on closed surfaces.
        """
        return self.border_distance > float(margin)

    def near_feature(self, margin: float) -> np.ndarray:
        """Mask of the points within ``margin`` of a sharp feature.

        Parameters
        ----------
        margin : float
            Distance along the surface.

        Returns
        -------
        ndarray of bool, shape (n,)
            ``feature_distance <= margin``; all False on smooth surfaces.
        """
        return self.feature_distance <= float(margin)


# ---------------------------------------------------------------------------
# base class
# ---------------------------------------------------------------------------


class Surface:
    """Base class of the analytic surfaces.

    Subclasses define :meth:`position`, :meth:`tangents`,
    :meth:`second_derivatives` and :meth:`area`, and may override
    :meth:`normal` and :meth:`curvature` with closed forms.  The generic
    implementations work from the derivatives of the parametrisation.

    Attributes
    ----------
    name : str
        Short name, as in :data:`SURFACES`.
    closed : bool
        True for surfaces without border.
    domain : tuple of two (float, float)
        Parameter rectangle ``((u0, u1), (v0, v1))``.
    periodic : tuple of two bool
        Whether ``u`` and ``v`` are periodic (then the upper end is excluded).
    """

    name: str = "surface"
    closed: bool = False
    periodic: tuple[bool, bool] = (False, False)
    domain: tuple[tuple[float, float], tuple[float, float]] = ((0.0, 1.0), (0.0, 1.0))

    # -- geometry to be provided by subclasses -----------------------------

    def position(self, u, v) -> np.ndarray:
        """Points ``X(u, v)``.

        Parameters
        ----------
        u, v : array_like, shape (n,)
            Parameters (scalars are treated as length-1 arrays).

        Returns
        -------
        ndarray, shape (n, 3)
        """
        raise NotImplementedError

    def tangents(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Analytic first derivatives ``X_u`` and ``X_v``.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        X_u, X_v : ndarray, shape (n, 3)
        """
        raise NotImplementedError

    def second_derivatives(self, u, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Analytic second derivatives ``X_uu``, ``X_uv``, ``X_vv``.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        X_uu, X_uv, X_vv : ndarray, shape (n, 3)
        """
        raise NotImplementedError

    def area(self) -> float:
        """Exact total area of the surface.

        Returns
        -------
        float
        """
        raise NotImplementedError

    def _extent(self) -> tuple[float, float]:
        """Typical 3-D lengths of the domain along u and v (grid aspect)."""
        (u0, u1), (v0, v1) = self.domain
        return u1 - u0, v1 - v0

    # -- generic differential geometry -------------------------------------

    def normal(self, u, v) -> np.ndarray:
        """Unit normal, oriented as documented for each surface.

        The generic version is ``X_u x X_v / |X_u x X_v|``; every
        parametrisation in this module is chosen so that this has the
        documented orientation.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n, 3)
        """
        xu, xv = self.tangents(u, v)
        return _unit(np.cross(xu, xv))

    def area_element(self, u, v) -> np.ndarray:
        """Area element ``|X_u x X_v|``.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n,)
        """
        xu, xv = self.tangents(u, v)
        return np.linalg.norm(np.cross(xu, xv), axis=1)

    def curvature_from_derivatives(self, u, v) -> Curvature:
        """Curvatures from the analytic derivatives, by the general formulas.

        Builds ``I`` and ``II_ab = X_ab . n`` from :meth:`tangents`,
        :meth:`second_derivatives` and :meth:`normal`, expresses the shape
        operator ``S = -I^{-1} II`` in the orthonormal tangent frame
        ``e1 = X_u / |X_u|``, ``e2 = n x e1`` and diagonalises it in closed
        form.  Needs a regular parametrisation (``X_u != 0``).

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        Curvature
        """
        u, v = _as_uv(u, v)
        xu, xv = self.tangents(u, v)
        xuu, xuv, xvv = self.second_derivatives(u, v)
        nrm = self.normal(u, v)
        e_ = _dot(xu, xu)
        f_ = _dot(xu, xv)
        g_ = _dot(xv, xv)
        det = e_ * g_ - f_ * f_
        l_ = _dot(xuu, nrm)
        m_ = _dot(xuv, nrm)
        n_ = _dot(xvv, nrm)
        e1 = _unit(xu)
        e2 = np.cross(nrm, e1)

        def coords(e):  # parameter coordinates (a, b) with a X_u + b X_v = e
            p = _dot(xu, e)
            q = _dot(xv, e)
            return (g_ * p - f_ * q) / det, (e_ * q - f_ * p) / det

        def second_form(p, q):
            return l_ * p[0] * q[0] + m_ * (p[0] * q[1] + p[1] * q[0]) + n_ * p[1] * q[1]

        p1 = coords(e1)
        p2 = coords(e2)
        return _curvature_in_frame(
            e1, e2, -second_form(p1, p1), -second_form(p1, p2), -second_form(p2, p2)
        )

    def curvature(self, u, v) -> Curvature:
        """Exact curvatures and principal directions.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        Curvature
        """
        return self.curvature_from_derivatives(u, v)

    def border_distance(self, u, v) -> np.ndarray:
        """Lower bound on the distance along the surface to the border.

        The generic version is the parameter distance to the edges of the
        non-periodic parameter directions, a lower bound whenever the metric
        dominates the Euclidean metric of the parameters in those directions
        (true for every open surface here).

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n,)
            ``inf`` everywhere on closed surfaces.
        """
        u, v = _as_uv(u, v)
        out = np.full(u.shape, np.inf)
        if self.closed:
            return out
        for t, (t0, t1), per in zip((u, v), self.domain, self.periodic):
            if not per:
                out = np.minimum(out, np.minimum(t - t0, t1 - t))
        return out

    def feature_distance(self, u, v) -> np.ndarray:
        """Distance along the surface to the nearest sharp feature.

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n,)
            ``inf`` for smooth surfaces.
        """
        u, _ = _as_uv(u, v)
        return np.full(u.shape, np.inf)

    # -- parameter samplers ------------------------------------------------

    def _grid_axes(self, n: int):
        """1-D grid axes and their spacings for about ``n`` grid points."""
        lu, lv = self._extent()
        counts = (
            int(round(math.sqrt(n * lu / lv))),
            int(round(math.sqrt(n * lv / lu))),
        )
        axes = []
        steps = []
        for k, (t0, t1), per in zip(counts, self.domain, self.periodic):
            if per:
                k = max(k, 3)
                axes.append(t0 + (t1 - t0) * np.arange(k, dtype=np.float64) / k)
                steps.append((t1 - t0) / k)
            else:
                k = max(k, 2)
                axes.append(np.linspace(t0, t1, k))
                steps.append((t1 - t0) / (k - 1))
        return axes[0], axes[1], steps[0], steps[1]

    def _grid_uv(self, n: int):
        us, vs, _, _ = self._grid_axes(n)
        uu, vv = np.meshgrid(us, vs, indexing="ij")
        return uu.ravel(), vv.ravel()

    def _into_domain(self, u: np.ndarray, v: np.ndarray):
        out = []
        for t, (t0, t1), per in zip((u, v), self.domain, self.periodic):
            out.append(_wrap(t, t0, t1) if per else _reflect(t, t0, t1))
        return out[0], out[1]

    def _jittered_uv(self, n: int, rng: np.random.Generator):
        us, vs, du, dv = self._grid_axes(n)
        uu, vv = np.meshgrid(us, vs, indexing="ij")
        uu = uu.ravel() + rng.uniform(-0.25, 0.25, uu.size) * du
        vv = vv.ravel() + rng.uniform(-0.25, 0.25, vv.size) * dv
        return self._into_domain(uu, vv)

    def _from_unit_square(self, t1: np.ndarray, t2: np.ndarray):
        """Map the unit square to the domain (area-preserving if possible).

        The generic map is linear: ``u`` from ``t1`` and ``v`` from ``t2``.
        """
        (u0, u1), (v0, v1) = self.domain
        return u0 + (u1 - u0) * t1, v0 + (v1 - v0) * t2

    def _fibonacci_uv(self, n: int):
        return self._from_unit_square(*_fibonacci_unit(n))

    def _area_element_bound(self) -> float:
        """An upper bound of ``|X_u x X_v|`` (dense grid maximum + 2 %)."""
        bound = getattr(self, "_cached_bound", None)
        if bound is None:
            (u0, u1), (v0, v1) = self.domain
            uu, vv = np.meshgrid(np.linspace(u0, u1, 257), np.linspace(v0, v1, 257))
            bound = 1.02 * float(np.max(self.area_element(uu.ravel(), vv.ravel())))
            self._cached_bound = bound
        return bound

    def _random_uv(self, n: int, rng: np.random.Generator):
        """Area-uniform rejection sampling in the parameter rectangle."""
        (u0, u1), (v0, v1) = self.domain
        bound = self._area_element_bound()
        box = (u1 - u0) * (v1 - v0)
        while True:
            acceptance = min(1.0, self.area() / (bound * box))
            us, vs = [], []
            count = 0
            restart = False
            while count < n:
                m = int(1.2 * (n - count) / acceptance) + 64
                u = rng.uniform(u0, u1, m)
                v = rng.uniform(v0, v1, m)
                w = self.area_element(u, v)
                wmax = float(np.max(w))
                if wmax > bound:  # bound was too low: enlarge it and start over
                    bound = 1.05 * wmax
                    self._cached_bound = bound
                    restart = True
                    break
                keep = rng.uniform(0.0, bound, m) < w
                us.append(u[keep])
                vs.append(v[keep])
                count += int(keep.sum())
            if not restart:
                return np.concatenate(us)[:n], np.concatenate(vs)[:n]

    # -- public sampling ---------------------------------------------------

    def sample(self, n, sampler: str = "grid", noise: float = 0.0, seed=None) -> SurfaceSample:
        """Draw a point cloud with exact ground truth.

        Parameters
        ----------
        n : int
            Requested number of points (>= 4).  ``"fibonacci"`` and
            ``"random"`` return exactly ``n``; ``"grid"`` and ``"jittered"``
            return the nearest grid size.
        sampler : {"grid", "fibonacci", "random", "jittered"}
            See the module docstring.
        noise : float
            Standard deviation of isotropic Gaussian noise added to
            ``points``, as a fraction of the bounding-box diagonal of the clean
            points.
        seed : None, int, or numpy.random.Generator
            Passed to :func:`numpy.random.default_rng`; the same seed gives the
            same sample.

        Returns
        -------
        SurfaceSample

        Raises
        ------
        HeatcurvError
            For an unknown sampler, ``n < 4`` or a negative/non-finite noise.
        """
        if isinstance(n, bool) or not isinstance(n, Integral):
            raise HeatcurvError(f"n must be an integer, got {n!r}")
        n = int(n)
        if n < 4:
            raise HeatcurvError(f"n must be at least 4, got {n}")
        if sampler not in SAMPLERS:
            raise HeatcurvError(
                f"unknown sampler {sampler!r}; supported samplers: {', '.join(SAMPLERS)}"
            )
        rng = np.random.default_rng(seed)
        if sampler == "grid":
            u, v = self._grid_uv(n)
        elif sampler == "fibonacci":
            u, v = self._fibonacci_uv(n)
        elif sampler == "random":
            u, v = self._random_uv(n, rng)
        else:
            u, v = self._jittered_uv(n, rng)
        return self._make_sample(u, v, sampler, noise, rng)

    def sample_at(self, u, v, noise: float = 0.0, seed=None) -> SurfaceSample:
        """Build a :class:`SurfaceSample` at given parameters.

        Parameters
        ----------
        u, v : array_like, shape (n,)
            Parameters of the points.
        noise : float
            As in :meth:`sample`.
        seed : None, int, or numpy.random.Generator
            Seed of the noise.

        Returns
        -------
        SurfaceSample
            With ``sampler == "custom"``.
        """
        u, v = _as_uv(u, v)
        u, v = u.copy(), v.copy()  # never alias the caller's arrays
        return self._make_sample(u, v, "custom", noise, np.random.default_rng(seed))

    def _make_sample(self, u, v, sampler, noise, rng) -> SurfaceSample:
        noise = _finite("noise", noise)
        if noise < 0.0:
            raise HeatcurvError(f"noise must be >= 0, got {noise}")
        u, v = _as_uv(u, v)
        clean = self.position(u, v)
        curv = self.curvature(u, v)
        sigma = 0.0
        if noise > 0.0:
            diag = float(np.linalg.norm(clean.max(axis=0) - clean.min(axis=0)))
            sigma = noise * diag
            points = clean + rng.normal(0.0, sigma, clean.shape)
        else:
            points = clean.copy()
        return SurfaceSample(
            surface=self,
            sampler=sampler,
            noise=noise,
            sigma=sigma,
            points=points,
            clean_points=clean,
            u=u,
            v=v,
            normals=self.normal(u, v),
            mean=curv.mean,
            gaussian=curv.gaussian,
            k1=curv.k1,
            k2=curv.k2,
            d1=curv.d1,
            d2=curv.d2,
            umbilic=curv.umbilic,
            total_area=float(self.area()),
            border_distance=self.border_distance(u, v),
            feature_distance=self.feature_distance(u, v),
        )

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self._params().items())
        return f"{type(self).__name__}({params})"

    def _params(self) -> dict:
        return {}


# ---------------------------------------------------------------------------
# closed surfaces
# ---------------------------------------------------------------------------


class Sphere(Surface):
    """Sphere of radius ``R`` about ``center``, outward normals.

    ``X(u, v) = center + R (cos v cos u, cos v sin u, sin v)`` with longitude
    ``u`` in ``[0, 2 pi)`` and latitude ``v`` in ``[-pi/2, pi/2]``.
    Curvatures ``k1 = k2 = mean = 1/R``, ``gaussian = 1/R^2``; every point is
    umbilic (``d1`` is the east direction, ``d2`` north).  ``"grid"`` sampling
    gives the Fibonacci sphere (a latitude-longitude grid clusters at the poles).

    Parameters
    ----------
    radius : float
        ``R > 0``.
    center : array_like, shape (3,)
    """

    name = "sphere"
    closed = True
    periodic = (True, False)

    def __init__(self, radius: float = 1.0, center=(0.0, 0.0, 0.0)):
        self.radius = _positive("radius", radius)
        c = np.asarray(center, dtype=np.float64)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise HeatcurvError(f"center must be 3 finite numbers, got {center!r}")
        self.center = c
        self.domain = ((0.0, _TWO_PI), (-0.5 * math.pi, 0.5 * math.pi))

    def _params(self):
        return {"radius": self.radius, "center": tuple(self.center.tolist())}

    @staticmethod
    def _radial(u, v):
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        return _vec(u.size, cv * cu, cv * su, sv)

    def position(self, u, v):
        u, v = _as_uv(u, v)
        return self.center + self.radius * self._radial(u, v)

    def normal(self, u, v):
        u, v = _as_uv(u, v)
        return self._radial(u, v)

    def tangents(self, u, v):
        u, v = _as_uv(u, v)
        r = self.radius
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        xu = _vec(u.size, -r * cv * su, r * cv * cu, 0.0)
        xv = _vec(u.size, -r * sv * cu, -r * sv * su, r * cv)
        return xu, xv

    def second_derivatives(self, u, v):
        u, v = _as_uv(u, v)
        r = self.radius
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        xuu = _vec(u.size, -r * cv * cu, -r * cv * su, 0.0)
        xuv = _vec(u.size, r * sv * su, -r * sv * cu, 0.0)
        xvv = _vec(u.size, -r * cv * cu, -r * cv * su, -r * sv)
        return xuu, xuv, xvv

    def curvature(self, u, v):
        u, v = _as_uv(u, v)
        k = np.full(u.shape, 1.0 / self.radius)
        n = self._radial(u, v)
        east = _vec(u.size, -np.sin(u), np.cos(u), 0.0)  # unit even at the poles
        return Curvature(
            mean=k.copy(),
            gaussian=k * k,
            k1=k.copy(),
            k2=k.copy(),
            d1=east,
            d2=np.cross(n, east),
            umbilic=np.ones(u.shape, dtype=bool),
        )

    def area(self):
        return 4.0 * math.pi * self.radius**2

    def _from_unit_square(self, t1, t2):
        # Archimedes: z = sin(latitude) is area-uniform.
        return _TWO_PI * t2, np.arcsin(np.clip(1.0 - 2.0 * t1, -1.0, 1.0))

    def _grid_uv(self, n):
        return self._fibonacci_uv(n)

    def _jittered_uv(self, n, rng):
        # Move each Fibonacci point by up to +-0.25 cell along east and north
        # (cell side sqrt(4 pi / n) on the unit sphere) and project back.  A
        # jitter in the unit square would be badly anisotropic near the poles.
        u, v = self._fibonacci_uv(n)
        cell = math.sqrt(4.0 * math.pi / n)
        radial = self._radial(u, v)
        east = _vec(n, -np.sin(u), np.cos(u), 0.0)
        north = np.cross(radial, east)
        a = rng.uniform(-0.25, 0.25, n)[:, None] * cell
        b = rng.uniform(-0.25, 0.25, n)[:, None] * cell
        p = _unit(radial + a * east + b * north)
        u = _wrap(np.arctan2(p[:, 1], p[:, 0]), 0.0, _TWO_PI)
        v = np.arcsin(np.clip(p[:, 2], -1.0, 1.0))
        return u, v


class Torus(Surface):
    """Ring torus ``(sqrt(x^2 + y^2) - r2)^2 + z^2 = r1^2`` about the z axis.

    ``X(u, v) = ((r2 + r1 cos v) cos u, (r2 + r1 cos v) sin u, r1 sin v)``,
    ``u, v`` in ``[0, 2 pi)`` (``v`` is the tube angle, ``v = 0`` on the outer
    equator).  Outward normal ``n = (cos v cos u, cos v sin u, sin v)``;
    ``k1 = 1/r1`` along the tube (``d1 = X_v / r1``),
    ``k2 = cos v / (r2 + r1 cos v)`` along the parallels.

    Parameters
    ----------
    r1 : float
        Tube radius, ``0 < r1 < r2``.
    r2 : float
        Radius of the centre circle of the tube.
    """

    name = "torus"
    closed = True
    periodic = (True, True)

    def __init__(self, r1: float = 1.0, r2: float = 2.3701):
        self.r1 = _positive("r1", r1)
        self.r2 = _positive("r2", r2)
        if not self.r1 < self.r2:
            raise HeatcurvError(
                f"need r1 < r2 for a ring torus (r1 = tube radius), got r1={r1}, r2={r2}"
            )
        self.domain = ((0.0, _TWO_PI), (0.0, _TWO_PI))

    def _params(self):
        return {"r1": self.r1, "r2": self.r2}

    def _extent(self):
        return _TWO_PI * self.r2, _TWO_PI * self.r1

    def position(self, u, v):
        u, v = _as_uv(u, v)
        rho = self.r2 + self.r1 * np.cos(v)
        return _vec(u.size, rho * np.cos(u), rho * np.sin(u), self.r1 * np.sin(v))

    def normal(self, u, v):
        u, v = _as_uv(u, v)
        cv = np.cos(v)
        return _vec(u.size, cv * np.cos(u), cv * np.sin(u), np.sin(v))

    def tangents(self, u, v):
        u, v = _as_uv(u, v)
        r1 = self.r1
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        rho = self.r2 + r1 * cv
        return (
            _vec(u.size, -rho * su, rho * cu, 0.0),
            _vec(u.size, -r1 * sv * cu, -r1 * sv * su, r1 * cv),
        )

    def second_derivatives(self, u, v):
        u, v = _as_uv(u, v)
        r1 = self.r1
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        rho = self.r2 + r1 * cv
        return (
            _vec(u.size, -rho * cu, -rho * su, 0.0),
            _vec(u.size, r1 * sv * su, -r1 * sv * cu, 0.0),
            _vec(u.size, -r1 * cv * cu, -r1 * cv * su, -r1 * sv),
        )

    def curvature(self, u, v):
        u, v = _as_uv(u, v)
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        k1 = np.full(u.shape, 1.0 / self.r1)
        k2 = cv / (self.r2 + self.r1 * cv)
        d1 = _vec(u.size, -sv * cu, -sv * su, cv)  # meridian (around the tube)
        d2 = _vec(u.size, su, -cu, 0.0)  # n x d1
        return Curvature(
            mean=0.5 * (k1 + k2),
            gaussian=k1 * k2,
            k1=k1,
            k2=k2,
            d1=d1,
            d2=d2,
            umbilic=_umbilic_mask(k1, k2),
        )

    def area(self):
        return 4.0 * math.pi**2 * self.r1 * self.r2

    def _tube_angle(self, t: np.ndarray) -> np.ndarray:
        """Inverse CDF of the area element in ``v``: solve ``F(v) = t``.

        ``F(v) = (r2 v + r1 sin v) / (2 pi r2)`` is strictly increasing on
        ``[0, 2 pi]`` because ``r1 < r2``; vectorised bisection then Newton.
        """
        e = self.r1 / self.r2
        target = _TWO_PI * t
        lo = np.zeros_like(target)
        hi = np.full_like(target, _TWO_PI)
        for _ in range(56):
            mid = 0.5 * (lo + hi)
            below = mid + e * np.sin(mid) < target
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        v = 0.5 * (lo + hi)
        for _ in range(2):
            v = v - (v + e * np.sin(v) - target) / (1.0 + e * np.cos(v))
        return _wrap(v, 0.0, _TWO_PI)

    def _from_unit_square(self, t1, t2):
        return _TWO_PI * t2, self._tube_angle(t1)


class Cylinder(Surface):
    """Open circular cylinder about the z axis, normals away from the axis.

    ``X(u, v) = (R cos u, R sin u, v)``, ``u`` in ``[0, 2 pi)``, ``v`` in
    ``[-H/2, H/2]``; the border is the two end circles.  ``k1 = 1/R`` around
    the axis (``d1 = (-sin u, cos u, 0)``), ``k2 = 0`` along it
    (``d2 = (0, 0, 1)``).  ``border_distance`` is exact (``|v -+ H/2|``).

    Parameters
    ----------
    radius : float
        ``R > 0``.
    height : float
        ``H > 0``.
    """

    name = "cylinder"
    closed = False
    periodic = (True, False)

    def __init__(self, radius: float = 1.0, height: float = 2.0):
        self.radius = _positive("radius", radius)
        self.height = _positive("height", height)
        self.domain = ((0.0, _TWO_PI), (-0.5 * self.height, 0.5 * self.height))

    def _params(self):
        return {"radius": self.radius, "height": self.height}

    def _extent(self):
        return _TWO_PI * self.radius, self.height

    def position(self, u, v):
        u, v = _as_uv(u, v)
        return _vec(u.size, self.radius * np.cos(u), self.radius * np.sin(u), v)

    def normal(self, u, v):
        u, v = _as_uv(u, v)
        return _vec(u.size, np.cos(u), np.sin(u), 0.0)

    def tangents(self, u, v):
        u, v = _as_uv(u, v)
        r = self.radius
        return _vec(u.size, -r * np.sin(u), r * np.cos(u), 0.0), _vec(u.size, 0.0, 0.0, 1.0)

    def second_derivatives(self, u, v):
        u, v = _as_uv(u, v)
        r = self.radius
        zero = _vec(u.size, 0.0, 0.0, 0.0)
        return _vec(u.size, -r * np.cos(u), -r * np.sin(u), 0.0), zero, zero.copy()

    def curvature(self, u, v):
        u, v = _as_uv(u, v)
        k1 = np.full(u.shape, 1.0 / self.radius)
        k2 = np.zeros(u.shape)
        return Curvature(
            mean=0.5 * k1,
            gaussian=k1 * k2,
            k1=k1,
            k2=k2,
            d1=_vec(u.size, -np.sin(u), np.cos(u), 0.0),
            d2=_vec(u.size, 0.0, 0.0, 1.0),
            umbilic=_umbilic_mask(k1, k2),
        )

    def area(self):
        return _TWO_PI * self.radius * self.height

    def _from_unit_square(self, t1, t2):
        return _TWO_PI * t2, -0.5 * self.height + self.height * t1


# ---------------------------------------------------------------------------
# graphs z = f(x, y)
# ---------------------------------------------------------------------------


class Graph(Surface):
    """Graph ``z = f(x, y)`` over ``[-size, size]^2``, upward normals.

    The parameters are ``u = x``, ``v = y``.  Curvature comes from the
    general formulas (see :meth:`Surface.curvature_from_derivatives`); for a
    graph they reduce to ``n = (-f_x, -f_y, 1) / W``, ``W = sqrt(1 + f_x^2 +
    f_y^2)``, ``mean = -((1 + f_y^2) f_xx - 2 f_x f_y f_xy + (1 + f_x^2) f_yy)
    / (2 W^3)`` and ``gaussian = (f_xx f_yy - f_xy^2) / W^4``.  The area is a
    200 x 200 Gauss-Legendre quadrature of ``W``.  ``border_distance`` is the
    distance in ``(x, y)`` to the square's edge, a lower bound because the
    graph metric dominates the Euclidean metric of ``(x, y)``.  ``"fibonacci"``
    maps the lattice linearly to the square (area-uniform only for planes).

    Parameters
    ----------
    f, fx, fy, fxx, fxy, fyy : callable
        ``f(x, y)`` and its partial derivatives; called with two float64
        arrays of shape (n,), they may return arrays of shape (n,) or scalars.
    size : float
        Half-width of the square domain.
    name : str
        Name of the surface.
    """

    closed = False
    periodic = (False, False)

    def __init__(
        self,
        f: Callable,
        fx: Callable,
        fy: Callable,
        fxx: Callable,
        fxy: Callable,
        fyy: Callable,
        size: float = 1.0,
        name: str = "graph",
    ):
        funcs = {"f": f, "fx": fx, "fy": fy, "fxx": fxx, "fxy": fxy, "fyy": fyy}
        for label, fn in funcs.items():
            if not callable(fn):
                raise HeatcurvError(f"{label} must be a callable of (x, y), got {fn!r}")
        self._f, self._fx, self._fy = f, fx, fy
        self._fxx, self._fxy, self._fyy = fxx, fxy, fyy
        self.size = _positive("size", size)
        self.name = str(name)
        self.domain = ((-self.size, self.size), (-self.size, self.size))

    def _params(self):
        return {"size": self.size, "name": self.name}

    @staticmethod
    def _eval(fn, x, y, label):
        out = np.asarray(fn(x, y), dtype=np.float64)
        try:
            return np.broadcast_to(out, x.shape)
        except ValueError:
            raise HeatcurvError(
                f"{label}(x, y) returned shape {out.shape}, expected {x.shape} or a scalar"
            ) from None

    def position(self, u, v):
        u, v = _as_uv(u, v)
        return _vec(u.size, u, v, self._eval(self._f, u, v, "f"))

    def tangents(self, u, v):
        u, v = _as_uv(u, v)
        return (
            _vec(u.size, 1.0, 0.0, self._eval(self._fx, u, v, "fx")),
            _vec(u.size, 0.0, 1.0, self._eval(self._fy, u, v, "fy")),
        )

    def second_derivatives(self, u, v):
        u, v = _as_uv(u, v)
        return (
            _vec(u.size, 0.0, 0.0, self._eval(self._fxx, u, v, "fxx")),
            _vec(u.size, 0.0, 0.0, self._eval(self._fxy, u, v, "fxy")),
            _vec(u.size, 0.0, 0.0, self._eval(self._fyy, u, v, "fyy")),
        )

    def area(self):
        cached = getattr(self, "_cached_area", None)
        if cached is None:
            nodes, weights = np.polynomial.legendre.leggauss(200)
            x = self.size * nodes
            xx, yy = np.meshgrid(x, x, indexing="ij")
            w = self.area_element(xx.ravel(), yy.ravel()).reshape(xx.shape)
            cached = float(self.size**2 * (weights @ w @ weights))
            self._cached_area = cached
        return cached


class Paraboloid(Graph):
    """Paraboloid ``z = a (x^2 + y^2)`` over ``[-size, size]^2``.

    With upward normals an upward-opening paraboloid (``a > 0``) bends
    toward its normal, so its curvatures are negative (``-2a`` at the origin,
    an umbilic).

    Parameters
    ----------
    a : float
    size : float
    """

    name = "paraboloid"

    def __init__(self, a: float = 0.5, size: float = 1.0):
        a = _finite("a", a)
        self.a = a
        super().__init__(
            lambda x, y: a * (x * x + y * y),
            lambda x, y: 2.0 * a * x,
            lambda x, y: 2.0 * a * y,
            lambda x, y: 2.0 * a,
            lambda x, y: 0.0,
            lambda x, y: 2.0 * a,
            size=size,
            name="paraboloid",
        )

    def _params(self):
        return {"a": self.a, "size": self.size}


class Saddle(Graph):
    """Hyperbolic paraboloid ``z = a (x^2 - y^2)`` over ``[-size, size]^2``.

    Parameters
    ----------
    a : float
    size : float
    """

    name = "saddle"

    def __init__(self, a: float = 0.5, size: float = 1.0):
        a = _finite("a", a)
        self.a = a
        super().__init__(
            lambda x, y: a * (x * x - y * y),
            lambda x, y: 2.0 * a * x,
            lambda x, y: -2.0 * a * y,
            lambda x, y: 2.0 * a,
            lambda x, y: 0.0,
            lambda x, y: -2.0 * a,
            size=size,
            name="saddle",
        )

    def _params(self):
        return {"a": self.a, "size": self.size}


class Arch(Graph):
    """Parabolic-cylinder arch ``z = -a x^2`` over ``[-size, size]^2``.

    A ridge along the y axis: ``k1 = 2a / (1 + 4 a^2 x^2)^{3/2} > 0`` across
    it (for ``a > 0``), ``k2 = 0`` along it, Gaussian curvature 0.

    Parameters
    ----------
    a : float
    size : float
    """

    name = "arch"

    def __init__(self, a: float = 0.5, size: float = 1.0):
        a = _finite("a", a)
        self.a = a
        super().__init__(
            lambda x, y: -a * x * x,
            lambda x, y: -2.0 * a * x,
            lambda x, y: 0.0,
            lambda x, y: -2.0 * a,
            lambda x, y: 0.0,
            lambda x, y: 0.0,
            size=size,
            name="arch",
        )

    def _params(self):
        return {"a": self.a, "size": self.size}


class Plane(Graph):
    """The square ``z = 0``, ``[-size, size]^2``, normal ``(0, 0, 1)``.

    All curvatures are 0 and every point is umbilic (``d1 = e_x``,
    ``d2 = e_y``).  ``border_distance`` is exact.

    Parameters
    ----------
    size : float
    """

    name = "plane"

    def __init__(self, size: float = 1.0):
        super().__init__(
            lambda x, y: 0.0,
            lambda x, y: 0.0,
            lambda x, y: 0.0,
            lambda x, y: 0.0,
            lambda x, y: 0.0,
            lambda x, y: 0.0,
            size=size,
            name="plane",
        )

    def _params(self):
        return {"size": self.size}

    def area(self):
        return (2.0 * self.size) ** 2


# ---------------------------------------------------------------------------
# folded square (sharp feature)
# ---------------------------------------------------------------------------


class FoldedSquare(Surface):
    """Square folded along the y axis into a roof (the paper's Fig. 10).

    The parameter square ``[-size, size]^2`` is mapped isometrically,
    ``X(u, v) = (u cos b, v, -|u| sin b)`` with ``b = (180 - interior_angle) / 2``
    degrees, so the two halves ``u < 0`` and ``u > 0`` are planar rectangles
    meeting at the ridge ``u = 0`` (the top, on the y axis) with the given
    interior (dihedral) angle; the face normals (upward,
    ``(sign(u) sin b, 0, cos b)``) differ by ``180 - interior_angle`` degrees.

    Curvature is 0 on both faces and every point is reported umbilic
    (``d1 = X_u / |X_u|``, ``d2 = (0, 1, 0)``).  The fold itself is singular:
    there the values are conventions (normal ``(0, 0, 1)``, the bisector;
    ``X_u`` the central derivative ``(cos b, 0, 0)``; curvature 0), so
    exclude it with :meth:`fold_distance` /
    :attr:`SurfaceSample.feature_distance`.

    Parameters
    ----------
    interior_angle : float
        Angle between the two halves in degrees, ``0 < angle <= 180``
        (180 is flat).
    size : float
        Half-width of the square.
    """

    name = "folded_square"
    closed = False
    periodic = (False, False)

    def __init__(self, interior_angle: float = 90.0, size: float = 1.0):
        angle = _finite("interior_angle", interior_angle)
        if not 0.0 < angle <= 180.0:
            raise HeatcurvError(
                f"interior_angle must be in (0, 180] degrees, got {interior_angle!r}"
            )
        self.interior_angle = angle
        self.size = _positive("size", size)
        self.beta = math.radians(0.5 * (180.0 - angle))
        self.domain = ((-self.size, self.size), (-self.size, self.size))

    def _params(self):
        return {"interior_angle": self.interior_angle, "size": self.size}

    def position(self, u, v):
        u, v = _as_uv(u, v)
        return _vec(u.size, u * math.cos(self.beta), v, -np.abs(u) * math.sin(self.beta))

    def tangents(self, u, v):
        u, v = _as_uv(u, v)
        xu = _vec(u.size, math.cos(self.beta), 0.0, -np.sign(u) * math.sin(self.beta))
        return xu, _vec(u.size, 0.0, 1.0, 0.0)

    def second_derivatives(self, u, v):
        u, v = _as_uv(u, v)
        zero = _vec(u.size, 0.0, 0.0, 0.0)
        return zero, zero.copy(), zero.copy()

    def normal(self, u, v):
        u, v = _as_uv(u, v)
        s = np.sign(u)
        n = _vec(u.size, s * math.sin(self.beta), 0.0, math.cos(self.beta))
        return _unit(n)

    def curvature(self, u, v):
        u, v = _as_uv(u, v)
        xu, _ = self.tangents(u, v)
        zero = np.zeros(u.shape)
        return Curvature(
            mean=zero.copy(),
            gaussian=zero.copy(),
            k1=zero.copy(),
            k2=zero.copy(),
            d1=_unit(xu),
            d2=_vec(u.size, 0.0, 1.0, 0.0),
            umbilic=np.ones(u.shape, dtype=bool),
        )

    def area(self):
        return (2.0 * self.size) ** 2

    def fold_distance(self, u, v) -> np.ndarray:
        """Distance to the fold line, along the surface (equal to the 3-D one).

        Parameters
        ----------
        u, v : array_like, shape (n,)

        Returns
        -------
        ndarray, shape (n,)
            ``|u|``.
        """
        u, _ = _as_uv(u, v)
        return np.abs(u)

    def feature_distance(self, u, v) -> np.ndarray:
        """Same as :meth:`fold_distance`."""
        return self.fold_distance(u, v)


# ---------------------------------------------------------------------------
# registry
# ---------------------------------------------------------------------------

#: Ready-to-use surfaces by name (:class:`Graph` is not listed: it needs ``f``).
SURFACES: dict[str, type[Surface]] = {
    "sphere": Sphere,
    "torus": Torus,
    "paraboloid": Paraboloid,
    "saddle": Saddle,
    "arch": Arch,
    "plane": Plane,
    "cylinder": Cylinder,
    "folded_square": FoldedSquare,
}


def get(name: str, **kwargs) -> Surface:
    """Construct a surface by name.

    Parameters
    ----------
    name : str
        A key of :data:`SURFACES` (case-insensitive; ``-`` and spaces count as
        ``_``).
    **kwargs
        Constructor parameters.

    Returns
    -------
    Surface

    Raises
    ------
    HeatcurvError
        For an unknown name (the message lists the known ones) or bad
        parameters.
    """
    key = str(name).strip().lower().replace("-", "_").replace(" ", "_")
    if key not in SURFACES:
        raise HeatcurvError(
            f"unknown surface {name!r}; known surfaces: {', '.join(sorted(SURFACES))}"
        )
    try:
        return SURFACES[key](**kwargs)
    except TypeError as exc:
        raise HeatcurvError(f"bad parameters for surface {key!r}: {exc}") from exc
