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
Closed surfaces (:class:`Sphere`, :class:`Ellipsoid`, :class:`Torus`): outward.  Graphs
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
    degenerates at the poles, so ``"grid"`` gives the Fibonacci sphere there
    (and on the :class:`Ellipsoid`, the Fibonacci sphere mapped, see below).
``"fibonacci"``
    The 2-D Fibonacci lattice ``((i + 0.5) / n, frac(i * golden))`` in the
    unit square, mapped by the surface's area-preserving map where it has one
    (sphere: the classic Fibonacci sphere, torus: inverse CDF of the area
    element in the tube angle, cylinder: linear) and by the plain linear
    parameter map otherwise (graphs, plane, folded square: *not*
    area-uniform on curved graphs).  The :class:`Ellipsoid` takes the
    sphere's lattice in its (longitude, latitude) parameters, i.e. the
    Fibonacci sphere stretched by ``diag(a, b, c)``: nearly uniform in
    parameter space but *not* area-uniform (denser where the stretch is
    smaller).  Exactly ``n`` points.
``"random"``
    Area-uniform random points, exactly ``n``, by rejection sampling in the
    parameter domain with acceptance ``|X_u x X_v| / max``.
``"jittered"``
    The grid with every point moved uniformly within +-0.25 cell in parameter
    space (reflected back at a domain border, wrapped in periodic
    directions).  On the sphere the jitter moves the
    Fibonacci points, along the east and north directions by up to
    +-0.25 cell (cell side ``sqrt(4 pi / n) R``), then projected back; the
    :class:`Ellipsoid` maps the jittered unit-sphere points the same way as
    its ``"fibonacci"`` lattice.
``"scan"``
    A simulated terrestrial / structured-light scan, see :meth:`Surface.scan`:
    rays on a regular azimuth x elevation grid from a few viewpoints, first
    hits kept, grazing hits (incidence > 80 degrees) dropped.  The density
    varies (overlapping scans, scan lines, fall-off with distance and
    incidence), parts of the surface may stay unseen (holes), and the count
    is about ``n`` (exactly ``n`` unless the scan came out short, see
    :meth:`Surface.scan`).  ``border_distance`` then also bounds the distance
    to the unseen region, approximately.

Inverse parametrisation and rays
--------------------------------
Every surface also has an inverse parametrisation :meth:`Surface.parameters_of`
(``position(parameters_of(p)) == p`` up to rounding for points on the
surface), an implicit function :meth:`Surface.implicit` (zero on the surface,
positive on the side the normal points to) and a vectorised first-hit ray
caster :meth:`Surface.ray_intersect` (closed form for the sphere, ellipsoid
and cylinder, safe marching plus bisection on the implicit function for the
others).

``noise > 0`` adds isotropic Gaussian noise of standard deviation
``noise * diag`` (``diag`` = bounding-box diagonal of the clean points); the
exact quantities are always those of the clean points.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from numbers import Integral, Real
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from heatcurv.errors import HeatcurvError

__all__ = [
    "Arch",
    "Curvature",
    "Cylinder",
    "Ellipsoid",
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
SAMPLERS = ("grid", "fibonacci", "random", "jittered", "scan")

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


def _check_n(n) -> int:
    """Validate a requested point count (an integer >= 4)."""
    if isinstance(n, bool) or not isinstance(n, Integral):
        raise HeatcurvError(f"n must be an integer, got {n!r}")
    n = int(n)
    if n < 4:
        raise HeatcurvError(f"n must be at least 4, got {n}")
    return n


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


def _as_points(points, name: str = "points") -> np.ndarray:
    """Return ``points`` as a finite float64 array of shape (n, 3)."""
    try:
        p = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise HeatcurvError(f"{name} must be a numeric array of shape (n, 3): {exc}") from exc
    if p.ndim == 1 and p.shape[0] == 3:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 3:
        raise HeatcurvError(f"{name} must have shape (n, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise HeatcurvError(f"{name} must be finite (found NaN or inf)")
    return p


def _as_rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    """Broadcast ray origins and directions to (m, 3); directions made unit."""
    o = _as_points(origins, "origins")
    d = _as_points(directions, "directions")
    try:
        o, d = np.broadcast_arrays(o, d)
    except ValueError:
        raise HeatcurvError(
            f"origins and directions must broadcast, got shapes {o.shape} and {d.shape}"
        ) from None
    length = np.linalg.norm(d, axis=1)
    if np.any(length == 0.0):
        raise HeatcurvError("ray directions must be non-zero")
    return np.ascontiguousarray(o), d / length[:, None]


def _slab(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Entry and exit ray parameters of the box ``[lo, hi]`` (entry clipped at 0).

    Shapes: ``o``, ``d`` (m, 3); returns two arrays of shape (m,); the ray
    misses the box where ``entry >= exit``.
    """
    safe = np.where(d == 0.0, 1e-300, d)
    ta = (lo - o) / safe
    tb = (hi - o) / safe
    enter = np.max(np.minimum(ta, tb), axis=1)
    leave = np.min(np.maximum(ta, tb), axis=1)
    return np.maximum(enter, 0.0), leave


def _first_quadric_root(qa, qb, qc, valid=None, tmin=0.0):
    """Smallest root ``t > tmin`` of ``qa t^2 + 2 qb t + qc = 0`` (``inf`` if none).

    Vectorised over arrays of shape (m,), cancellation-free.  ``valid`` is an
    optional callable ``valid(t) -> bool array`` a root must also satisfy
    (e.g. lying within the cylinder's height).
    """
    disc = qb * qb - qa * qc
    ok = (disc >= 0.0) & (qa > 0.0)
    root = np.sqrt(np.where(ok, disc, 0.0))
    q = -(qb + np.copysign(root, qb))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(ok, q / qa, np.inf)
        r2 = np.where(ok & (q != 0.0), qc / q, np.inf)
    near = np.minimum(r1, r2)
    far = np.maximum(r1, r2)
    out = np.full(qa.shape, np.inf)
    for t in (far, near):  # the nearer valid root wins, so assign it last
        good = ok & np.isfinite(t) & (t > tmin)
        if valid is not None:
            good &= valid(np.where(good, t, 0.0))
        out = np.where(good, t, out)
    return out


def _longitude(p: np.ndarray) -> np.ndarray:
    """Angle of the points ``p`` (shape (n, 3)) about the z axis, in ``[0, 2 pi)``."""
    return _wrap(np.arctan2(p[:, 1], p[:, 0]), 0.0, _TWO_PI)


def _radial(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit vectors ``(cos v cos u, cos v sin u, sin v)``, shape (n, 3)."""
    cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
    return _vec(u.size, cv * cu, cv * su, sv)


def _east(u: np.ndarray) -> np.ndarray:
    """Unit vectors ``(-sin u, cos u, 0)`` along the parallels, shape (n, 3)."""
    return _vec(u.size, -np.sin(u), np.cos(u), 0.0)


def _check_noise(noise) -> float:
    """Validate a relative noise level (finite, >= 0)."""
    noise = _finite("noise", noise)
    if noise < 0.0:
        raise HeatcurvError(f"noise must be >= 0, got {noise}")
    return noise


def _cached_in(attr: str):
    """Decorator: keep the result of an argument-less method in ``self.<attr>``.

    The value is computed on the first call (or whenever the attribute is
    missing or None) and returned from the attribute afterwards.
    """

    def decorate(method):
        @functools.wraps(method)
        def cached(self):
            value = getattr(self, attr, None)
            if value is None:
                value = method(self)
                setattr(self, attr, value)
            return value

        return cached

    return decorate


def _view_positions(views, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Viewpoints from ``(azimuth, elevation, distance)`` triples, shape (k, 3).

    Angles in degrees about the centre of the box ``[lo, hi]``, distances in
    bounding radii (half the box diagonal).
    """
    az = np.radians([a for a, _, _ in views])
    el = np.radians([e for _, e, _ in views])
    dist = np.array([r for _, _, r in views]) * 0.5 * float(np.linalg.norm(hi - lo))
    unit = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return 0.5 * (lo + hi) + dist[:, None] * unit


#: (azimuth, elevation, distance) of the default scan viewpoints around an
#: object and above a graph patch: degrees, and bounding radii (half the
#: bounding-box diagonal) from the box centre; see
#: :meth:`Surface.default_viewpoints`.  Different distances give the scans
#: different densities (one angular step for all), as with a real scanner
#: set up at several stations.
_AROUND = ((30.0, 35.0, 2.5), (150.0, -25.0, 3.0), (270.0, 10.0, 3.5))
_ABOVE = ((0.0, 65.0, 2.0), (120.0, 55.0, 2.75), (240.0, 72.0, 3.5))


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


def _principal_curvature(k1, k2, d1, d2, mean=None, umbilic=None) -> Curvature:
    """A :class:`Curvature` from principal curvatures and directions.

    ``mean`` defaults to ``(k1 + k2) / 2`` and ``umbilic`` to the tolerance
    test documented in :class:`Curvature`; ``gaussian`` is ``k1 * k2``.
    """
    return Curvature(
        mean=0.5 * (k1 + k2) if mean is None else mean,
        gaussian=k1 * k2,
        k1=k1,
        k2=k2,
        d1=d1,
        d2=d2,
        umbilic=_umbilic_mask(k1, k2) if umbilic is None else umbilic,
    )


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
    return _principal_curvature(k1, k2, d1, d2, mean=mean)


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
    viewpoints : ndarray, shape (m, 3), or None
        ``"scan"`` samples: the scanner positions; None for the other samplers.
    viewpoint_index : ndarray of int, shape (n,), or None
        ``"scan"`` samples: the viewpoint (row of ``viewpoints``) whose ray
        produced each point; None for the other samplers.
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
    viewpoints: np.ndarray | None = field(default=None, repr=False)
    viewpoint_index: np.ndarray | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def transformed(self, scale: float = 1.0, rotation=None, translation=None) -> "SurfaceSample":
        """The same sample after ``x -> scale * rotation @ x + translation``.

        Every exact quantity is mapped accordingly: normals and principal
        directions are rotated, curvatures divided by ``scale`` (Gaussian by
        ``scale**2``), ``total_area`` multiplied by ``scale**2``, distances
        (``border_distance``, ``feature_distance``, ``sigma``) by ``scale``;
        ``points`` (noise included) and ``viewpoints`` are moved like the clean
        points.  ``surface``, ``u`` and ``v`` still refer to the untransformed
        surface.

        Parameters
        ----------
        scale : float
            ``> 0``.
        rotation : array_like, shape (3, 3), optional
            A proper rotation (orthonormal, determinant +1, to 1e-9); a
            reflection would break ``d1 x d2 = n``.  Default identity.
        translation : array_like, shape (3,), optional
            Default zero.

        Returns
        -------
        SurfaceSample
        """
        s = _positive("scale", scale)
        rot = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        if rot.shape != (3, 3) or not np.all(np.isfinite(rot)):
            raise HeatcurvError(f"rotation must be a finite 3 x 3 matrix, got shape {rot.shape}")
        if not (np.allclose(rot @ rot.T, np.eye(3), atol=1e-9) and np.linalg.det(rot) > 0):
            raise HeatcurvError("rotation must be a proper rotation matrix (orthonormal, det = +1)")
        shift = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
        if shift.shape != (3,) or not np.all(np.isfinite(shift)):
            raise HeatcurvError(f"translation must be 3 finite numbers, got {translation!r}")

        def move(p):
            return s * (p @ rot.T) + shift

        return replace(
            self,
            points=move(self.points),
            clean_points=move(self.clean_points),
            normals=self.normals @ rot.T,
            d1=self.d1 @ rot.T,
            d2=self.d2 @ rot.T,
            mean=self.mean / s,
            k1=self.k1 / s,
            k2=self.k2 / s,
            gaussian=self.gaussian / (s * s),
            sigma=self.sigma * s,
            total_area=self.total_area * s * s,
            border_distance=self.border_distance * s,
            feature_distance=self.feature_distance * s,
            viewpoints=None if self.viewpoints is None else move(self.viewpoints),
        )

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

    # -- inverse parametrisation, implicit form, rays ----------------------

    def parameters_of(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Parameters ``(u, v)`` of points on the surface, the inverse of :meth:`position`.

        For points on the surface ``position(*parameters_of(p))`` reproduces
        ``p`` up to rounding.  Points off the surface are mapped to the
        parameters of a nearby surface point (a radial or vertical projection,
        documented per surface), not necessarily the nearest one.  Periodic
        parameters are wrapped into the domain, the others are *not* clipped.

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        u, v : ndarray, shape (n,)
        """
        raise NotImplementedError

    def implicit(self, points) -> np.ndarray:
        """An implicit function of the surface (ignoring the border of open ones).

        Zero on the surface, positive on the side the normal points to
        (outside for closed surfaces, above for graphs).  It is
        Lipschitz-continuous along any unit direction with the constant
        :meth:`_implicit_lipschitz`, which lets :meth:`ray_intersect` march
        safely.

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        ndarray, shape (n,)
        """
        raise NotImplementedError

    def _implicit_lipschitz(self) -> float:
        """Upper bound of ``|grad implicit|`` (a distance function has 1)."""
        return 1.0

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """An axis-aligned box containing the surface (tight for the closed forms).

        Returns
        -------
        lo, hi : ndarray, shape (3,)
        """
        raise NotImplementedError

    def _march_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Box the ray marcher searches: the bounding box, slightly padded.

        Open surfaces whose border is given by the box (graphs) override this
        so that the box does not extend past the border.
        """
        lo, hi = self.bounding_box()
        pad = 1e-6 * float(np.linalg.norm(hi - lo)) + 1e-300
        return lo - pad, hi + pad

    def ray_intersect(self, origins, directions) -> np.ndarray:
        """Distance along each ray to its first intersection with the surface.

        Parameters
        ----------
        origins : array_like, shape (m, 3) or (3,)
            Ray origins (broadcast against ``directions``).
        directions : array_like, shape (m, 3) or (3,)
            Ray directions, need not be unit length.

        Returns
        -------
        ndarray, shape (m,)
            ``t > 0`` such that ``origin + t * direction / |direction|`` is the
            first surface point hit (the border of open surfaces respected),
            ``inf`` where the ray misses.  Closed forms for the
            :class:`Sphere`, :class:`Ellipsoid` and :class:`Cylinder`; the
            other surfaces march along the ray with steps
            ``max(|implicit| / Lipschitz, 2e-4 * box diagonal)`` (a step
            that cannot jump over the surface unless the ray stays within
            ~``2e-4`` box diagonals of it, i.e. is grazing), then bisect the
            first sign change to full precision.
        """
        o, d = _as_rays(origins, directions)
        return self._intersect(o, d)

    def _intersect(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Generic first hit: safe marching plus bisection (unit ``d``)."""
        m = o.shape[0]
        out = np.full(m, np.inf)
        lo, hi = self._march_box()
        enter, leave = _slab(o, d, lo, hi)
        idx = np.flatnonzero(enter < leave)
        if idx.size == 0:
            return out
        lip = float(self._implicit_lipschitz())
        hmin = 2e-4 * float(np.linalg.norm(hi - lo))
        oo, dd, t, t_end = o[idx], d[idx], enter[idx], leave[idx]
        g = self.implicit(oo + t[:, None] * dd)
        at_zero = g == 0.0
        out[idx[at_zero]] = t[at_zero]
        keep = ~at_zero
        idx, oo, dd, t, t_end, g = idx[keep], oo[keep], dd[keep], t[keep], t_end[keep], g[keep]
        b_ids, b_lo, b_hi, b_neg = [], [], [], []
        while idx.size:
            step = np.maximum(np.abs(g) / lip, hmin)
            tn = np.minimum(t + step, t_end)
            gn = self.implicit(oo + tn[:, None] * dd)
            cross = (gn == 0.0) | (np.signbit(gn) != np.signbit(g))
            if np.any(cross):
                b_ids.append(idx[cross])
                b_lo.append(t[cross])
                b_hi.append(tn[cross])
                b_neg.append(np.signbit(g[cross]))
            keep = ~(cross | (tn >= t_end))
            idx, oo, dd, t, t_end, g = idx[keep], oo[keep], dd[keep], tn[keep], t_end[keep], gn[keep]
        if not b_ids:
            return out
        ids = np.concatenate(b_ids)
        a, b = np.concatenate(b_lo), np.concatenate(b_hi)
        neg_a = np.concatenate(b_neg)
        oo, dd = o[ids], d[ids]
        for _ in range(200):  # bisection to adjacent floats (~60 halvings)
            mid = 0.5 * (a + b)
            if np.all((mid == a) | (mid == b)):
                break
            gm = self.implicit(oo + mid[:, None] * dd)
            zero = gm == 0.0
            same = (np.signbit(gm) == neg_a) & ~zero
            a = np.where(same | zero, mid, a)
            b = np.where(same, b, mid)
        out[ids] = 0.5 * (a + b)
        return out

    def default_viewpoints(self) -> np.ndarray:
        """Default scanner positions of :meth:`scan`.

        Three positions looking at the bounding-box centre from 2.5, 3 and 3.5
        bounding radii (half the bounding-box diagonal): for closed surfaces
        around the object at azimuths 30, 150, 270 degrees and elevations
        +35, -25, +10 degrees; graphs (and the folded square) are looked at
        from above, from 2, 2.75 and 3.5 bounding radii at azimuths 0, 120,
        240 and elevations 65, 55, 72 degrees (steeper than the surfaces'
        slopes, so only the upper side is seen); the cylinder from the side
        (azimuths as above) at heights +0.6, -0.6 and 0 half-heights, so the
        inside of the tube stays unseen.

        Returns
        -------
        ndarray, shape (3, 3)
        """
        return _view_positions(_AROUND, *self.bounding_box())

    def _bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre and radius (half the diagonal) of the bounding box's sphere."""
        lo, hi = self.bounding_box()
        return 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))

    def _scan_grid(self, viewpoints: np.ndarray, delta: float):
        """Rays of the angular scan grids: origins, unit directions, viewpoint index.

        Each viewpoint looks at the bounding-box centre; its rays are spaced
        ``delta`` radians in azimuth (about the viewpoint's vertical axis) and
        elevation, ordered in scan lines of constant azimuth, and limited to the
        cone around the bounding sphere.
        """
        centre, rb = self._bounding_sphere()
        origins, dirs, index = [], [], []
        for i, c in enumerate(viewpoints):
            fwd = centre - c
            dist = float(np.linalg.norm(fwd))
            f = fwd / dist
            half = min(math.asin(min(rb / dist, 1.0)) * 1.02, 0.5 * math.pi)
            up0 = np.array([0.0, 0.0, 1.0]) if abs(f[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
            right = np.cross(f, up0)
            right /= np.linalg.norm(right)
            up = np.cross(right, f)
            k = int(math.ceil(half / delta))
            ang = delta * np.arange(-k, k + 1, dtype=np.float64)
            phi, theta = np.meshgrid(ang, ang, indexing="ij")  # scan lines: constant azimuth
            phi, theta = phi.ravel(), theta.ravel()
            inside = np.cos(theta) * np.cos(phi) >= math.cos(half)
            phi, theta = phi[inside], theta[inside]
            ct = np.cos(theta)[:, None]
            d = ct * (np.cos(phi)[:, None] * f + np.sin(phi)[:, None] * right) + np.sin(theta)[:, None] * up
            dirs.append(d / np.linalg.norm(d, axis=1)[:, None])
            origins.append(np.broadcast_to(c, d.shape))
            index.append(np.full(d.shape[0], i, dtype=np.int64))
        return np.concatenate(origins), np.concatenate(dirs), np.concatenate(index)

    def _map_into_domain(self, u: np.ndarray, v: np.ndarray, bounded: Callable):
        """Wrap periodic parameters; map the others by ``bounded(t, t0, t1)``."""
        out = []
        for t, (t0, t1), per in zip((u, v), self.domain, self.periodic):
            out.append(_wrap(t, t0, t1) if per else bounded(t, t0, t1))
        return out[0], out[1]

    def _clip_uv(self, u: np.ndarray, v: np.ndarray):
        """Wrap periodic parameters and clip the others into the domain (rounding)."""
        return self._map_into_domain(u, v, np.clip)

    def _scan_hits(self, viewpoints: np.ndarray, delta: float, min_cos: float):
        """Cast the scan grid; the kept first hits' parameters and viewpoint index."""
        o, d, index = self._scan_grid(viewpoints, delta)
        t = self._intersect(o, d)
        hit = np.isfinite(t)
        o, d, t, index = o[hit], d[hit], t[hit], index[hit]
        u, v = self._clip_uv(*self.parameters_of(o + t[:, None] * d))
        facing = np.abs(_dot(self.normal(u, v), d)) >= min_cos
        return u[facing], v[facing], index[facing]

    def _covered(self, q: np.ndarray, nq: np.ndarray, viewpoints: np.ndarray, min_cos: float):
        """Which points ``q`` (normals ``nq``) some viewpoint sees unoccluded, not grazing."""
        lo, hi = self.bounding_box()
        tol = 1e-7 * float(np.linalg.norm(hi - lo))
        covered = np.zeros(q.shape[0], dtype=bool)
        for c in viewpoints:
            vec = q - c
            dist = np.linalg.norm(vec, axis=1)
            d = vec / dist[:, None]
            sel = np.flatnonzero(~covered & (np.abs(_dot(nq, d)) >= min_cos))
            if sel.size == 0:
                continue
            t = self._intersect(np.broadcast_to(c, (sel.size, 3)), d[sel])
            covered[sel[t >= dist[sel] - tol]] = True
        return covered

    def _scan_border_distance(self, u, v, viewpoints, min_cos, n):
        """``border_distance`` of scan points: min of the surface's and the hole's.

        The unseen region is found on a dense reference sample (the
        ``"grid"`` layout with ``clip(2 n, 4000, 100000)`` points): a reference
        point is seen if some viewpoint sees it unoccluded and within the
        incidence limit.  The distance to the unseen region is approximated
        by the 3-D distance to the nearest unseen reference point minus the
        largest reference nearest-neighbour distance (clipped at 0): close to
        a lower bound of the distance along the surface, to about one
        reference spacing.
        """
        own = self.border_distance(u, v)
        ur, vr = self._grid_uv(int(min(max(2 * n, 4000), 100000)))
        q = self.position(ur, vr)
        seen = self._covered(q, self.normal(ur, vr), viewpoints, min_cos)
        if np.all(seen):
            return own
        spacing = float(np.max(cKDTree(q).query(q, 2)[0][:, 1]))
        hole = cKDTree(q[~seen]).query(self.position(u, v))[0]
        return np.minimum(own, np.maximum(hole - spacing, 0.0))

    def scan(
        self,
        n,
        viewpoints=None,
        noise: float = 0.0,
        seed=None,
        max_incidence: float = 80.0,
    ) -> SurfaceSample:
        """A simulated terrestrial / structured-light scan with exact ground truth.

        From each viewpoint, rays are cast on a regular angular grid (scan
        lines of constant azimuth about the viewpoint's vertical axis, the same
        angular step in azimuth and elevation, covering the cone of the
        bounding sphere) and the *first* hit of each ray is kept, unless it
        is grazing (angle between ray and normal > ``max_incidence``).  Hits
        of all viewpoints are pooled, so the density varies: overlaps, scan
        lines, fall-off with distance and with incidence (``~ cos(incidence) /
        distance^2``); regions no viewpoint sees stay empty (holes, also on
        closed surfaces).  Open surfaces can be hit on either side (e.g. the
        inside of the :class:`Cylinder` through its ends, with viewpoints not
        of the default); ``normals`` keep the surface's orientation.

        The angular step is chosen from a coarse pilot scan so that the hit
        count is about ``1.03 n``; the excess hits are then dropped at random
        (seeded, order preserved), which gives exactly ``n`` points.  If a scan
        still comes out short after three refinements of the step (it should
        not), fewer points are returned.  The exact values at each hit come
        from its parameters, :meth:`parameters_of` of the hit point, so
        ``clean_points == position(u, v)`` exactly.  ``border_distance`` is
        the minimum of the surface's own and an approximate distance to the
        unseen region (see :meth:`_scan_border_distance`), so
        :meth:`SurfaceSample.interior` excludes the borders of holes as well.

        Parameters
        ----------
        n : int
            Requested number of points (>= 4).
        viewpoints : array_like, shape (m, 3), optional
            Scanner positions, each outside the bounding sphere (centre and
            half-diagonal of :meth:`bounding_box`); default
            :meth:`default_viewpoints`.
        noise : float
            As in :meth:`sample` (``noise * diag`` standard deviation).
        seed : None, int, or numpy.random.Generator
            Seeds the dropping of excess hits and the noise; same seed, same
            sample.
        max_incidence : float
            Largest kept angle between ray and surface normal, degrees in
            ``(0, 90)``.

        Returns
        -------
        SurfaceSample
            ``sampler == "scan"``, with ``viewpoints`` (m, 3) and
            ``viewpoint_index`` (n,) set.

        Raises
        ------
        HeatcurvError
            For ``n < 4``, bad viewpoints (shape, non-finite, inside the
            bounding sphere), a bad ``max_incidence`` or noise, or when no
            ray hits the surface.
        """
        n = _check_n(n)
        noise = _check_noise(noise)
        inc = _finite("max_incidence", max_incidence)
        if not 0.0 < inc < 90.0:
            raise HeatcurvError(f"max_incidence must be in (0, 90) degrees, got {max_incidence!r}")
        min_cos = math.cos(math.radians(inc))
        centre, rb = self._bounding_sphere()
        if viewpoints is None:
            vps = self.default_viewpoints()
        else:
            vps = _as_points(viewpoints, "viewpoints")
        far = np.linalg.norm(vps - centre, axis=1)
        if np.any(far <= rb * (1.0 + 1e-9)):
            raise HeatcurvError(
                f"scan viewpoints must lie outside the bounding sphere (centre {centre.tolist()}, "
                f"radius {rb:.6g}); distances {far.tolist()}"
            )
        rng = np.random.default_rng(seed)
        # pilot: ~3000 rays per viewpoint over the widest cone
        half = max(math.asin(min(rb / float(f), 1.0)) for f in far)
        delta0 = 1.02 * half * math.sqrt(math.pi / 3000.0)
        u, _, _ = self._scan_hits(vps, delta0, min_cos)
        if u.size == 0:
            raise HeatcurvError("no scan ray hit the surface from these viewpoints")
        target = 1.03 * n + 8
        delta = delta0 * math.sqrt(u.size / target)
        for _ in range(4):
            u, v, index = self._scan_hits(vps, delta, min_cos)
            if u.size >= n:
                break
            delta *= 0.99 * math.sqrt(max(u.size, 1) / target)
        if u.size > n:
            keep = np.sort(rng.choice(u.size, size=n, replace=False))
            u, v, index = u[keep], v[keep], index[keep]
        border = self._scan_border_distance(u, v, vps, min_cos, n)
        return self._make_sample(
            u, v, "scan", noise, rng, border_distance=border, viewpoints=vps, viewpoint_index=index
        )

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
        """Wrap periodic parameters and reflect the others back into the domain."""
        return self._map_into_domain(u, v, _reflect)

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

    @_cached_in("_cached_bound")
    def _area_element_bound(self) -> float:
        """An upper bound of ``|X_u x X_v|`` (dense grid maximum + 2 %)."""
        (u0, u1), (v0, v1) = self.domain
        uu, vv = np.meshgrid(np.linspace(u0, u1, 257), np.linspace(v0, v1, 257))
        return 1.02 * float(np.max(self.area_element(uu.ravel(), vv.ravel())))

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
            return the nearest grid size; ``"scan"`` about ``n`` (see
            :meth:`scan`).
        sampler : {"grid", "fibonacci", "random", "jittered", "scan"}
            See the module docstring; ``"scan"`` is :meth:`scan` with the
            default viewpoints.
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
        n = _check_n(n)
        if sampler not in SAMPLERS:
            raise HeatcurvError(
                f"unknown sampler {sampler!r}; supported samplers: {', '.join(SAMPLERS)}"
            )
        if sampler == "scan":
            return self.scan(n, noise=noise, seed=seed)
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

    def _make_sample(
        self, u, v, sampler, noise, rng, border_distance=None, viewpoints=None, viewpoint_index=None
    ) -> SurfaceSample:
        noise = _check_noise(noise)
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
            border_distance=(
                self.border_distance(u, v) if border_distance is None else border_distance
            ),
            feature_distance=self.feature_distance(u, v),
            viewpoints=viewpoints,
            viewpoint_index=viewpoint_index,
        )

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self._params().items())
        return f"{type(self).__name__}({params})"

    def _params(self) -> dict:
        return {}


# ---------------------------------------------------------------------------
# closed surfaces
# ---------------------------------------------------------------------------


class _LatitudeLongitude(Surface):
    """Closed surface parametrised like the sphere, by longitude and latitude.

    ``X(u, v) = center + (a cos v cos u, b cos v sin u, c sin v)`` with the
    semi-axes ``(a, b, c)`` of :meth:`_semi_axes`, longitude ``u`` in
    ``[0, 2 pi)`` and latitude ``v`` in ``[-pi/2, pi/2]``; the subclasses give
    the position, normal and closed-form curvature.  A latitude-longitude grid
    clusters at the poles, so the samplers use the Fibonacci sphere in these
    parameters: ``"fibonacci"`` and ``"grid"`` its lattice, ``"jittered"`` its
    points jittered along east and north on the unit sphere.
    """

    closed = True
    periodic = (True, False)
    domain = ((0.0, _TWO_PI), (-0.5 * math.pi, 0.5 * math.pi))

    def _semi_axes(self) -> tuple[float, float, float]:
        """The stretch ``(a, b, c)`` of the unit sphere's parametrisation."""
        raise NotImplementedError

    def _angle_frame(self, p: np.ndarray) -> np.ndarray:
        """Points in which longitude and latitude are the polar angles about the origin."""
        raise NotImplementedError

    def tangents(self, u, v):
        u, v = _as_uv(u, v)
        a, b, c = self._semi_axes()
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        return (
            _vec(u.size, -a * cv * su, b * cv * cu, 0.0),
            _vec(u.size, -a * sv * cu, -b * sv * su, c * cv),
        )

    def second_derivatives(self, u, v):
        u, v = _as_uv(u, v)
        a, b, c = self._semi_axes()
        cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
        return (
            _vec(u.size, -a * cv * cu, -b * cv * su, 0.0),
            _vec(u.size, a * sv * su, -b * sv * cu, 0.0),
            _vec(u.size, -a * cv * cu, -b * cv * su, -c * sv),
        )

    def _from_unit_square(self, t1, t2):
        # Archimedes: z = sin(latitude) is area-uniform on the sphere.
        return _TWO_PI * t2, np.arcsin(np.clip(1.0 - 2.0 * t1, -1.0, 1.0))

    def _grid_uv(self, n):
        return self._fibonacci_uv(n)

    def _jittered_uv(self, n, rng):
        """Fibonacci-sphere parameters moved by +-0.25 cell along east and north.

        Cell side ``sqrt(4 pi / n)`` on the unit sphere; the moved point is
        projected back onto the sphere (a jitter in the unit square would be
        badly anisotropic near the poles).  Returns longitude in ``[0, 2 pi)``
        and latitude, arrays of shape (n,).
        """
        u, v = self._fibonacci_uv(n)
        cell = math.sqrt(4.0 * math.pi / n)
        radial = _radial(u, v)
        east = _east(u)
        north = np.cross(radial, east)
        a = rng.uniform(-0.25, 0.25, n)[:, None] * cell
        b = rng.uniform(-0.25, 0.25, n)[:, None] * cell
        p = _unit(radial + a * east + b * north)
        return _longitude(p), np.arcsin(np.clip(p[:, 2], -1.0, 1.0))

    def parameters_of(self, points):
        """Longitude and latitude of ``points`` (a radial projection).

        On the :class:`Sphere` the angles of ``points`` seen from the centre,
        on the :class:`Ellipsoid` those of ``points / (a, b, c)``.

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        u, v : ndarray, shape (n,)
        """
        p = self._angle_frame(_as_points(points))
        return _longitude(p), np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1]))


class Sphere(_LatitudeLongitude):
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

    def __init__(self, radius: float = 1.0, center=(0.0, 0.0, 0.0)):
        self.radius = _positive("radius", radius)
        c = np.asarray(center, dtype=np.float64)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise HeatcurvError(f"center must be 3 finite numbers, got {center!r}")
        self.center = c

    def _params(self):
        return {"radius": self.radius, "center": tuple(self.center.tolist())}

    def _semi_axes(self):
        return self.radius, self.radius, self.radius

    def _angle_frame(self, p):
        return p - self.center

    def position(self, u, v):
        u, v = _as_uv(u, v)
        return self.center + self.radius * _radial(u, v)

    def normal(self, u, v):
        u, v = _as_uv(u, v)
        return _radial(u, v)

    def curvature(self, u, v):
        u, v = _as_uv(u, v)
        k = np.full(u.shape, 1.0 / self.radius)
        east = _east(u)  # unit even at the poles
        north = np.cross(_radial(u, v), east)
        every = np.ones(u.shape, dtype=bool)
        return _principal_curvature(k.copy(), k.copy(), east, north, mean=k, umbilic=every)

    def area(self):
        return 4.0 * math.pi * self.radius**2

    def implicit(self, points):
        """Signed distance ``|p - center| - R``, shape (n,)."""
        p = _as_points(points)
        return np.linalg.norm(p - self.center, axis=1) - self.radius

    def bounding_box(self):
        return self.center - self.radius, self.center + self.radius

    def _intersect(self, o, d):
        rel = o - self.center
        return _first_quadric_root(
            np.ones(o.shape[0]), _dot(rel, d), _dot(rel, rel) - self.radius**2
        )


class Ellipsoid(_LatitudeLongitude):
    """Ellipsoid ``x^2/a^2 + y^2/b^2 + z^2/c^2 = 1`` about the origin, outward normals.

    ``X(u, v) = (a cos v cos u, b cos v sin u, c sin v)`` with longitude ``u``
    in ``[0, 2 pi)`` and latitude ``v`` in ``[-pi/2, pi/2]`` (the sphere's
    parametrisation, stretched).  With distinct semi-axes ``k1 != k2``
    everywhere except at 4 umbilics (in the plane of the longest and the
    shortest axis).  Normal and curvature come from the implicit form
    ``F = x^2/a^2 + y^2/b^2 + z^2/c^2``: ``n = grad F / |grad F|`` and the
    shape operator ``P Hess(F) P / |grad F|`` (``P`` the tangent projector)
    in the frame ``e1 = (-a sin u, b cos u, 0) / |.|`` (east, also at the
    poles), ``e2 = n x e1``; so ``Gaussian = 1 / (a b c |g|^2)^2`` and ``mean
    = (a^2 + b^2 + c^2 - |X|^2) / (2 a^2 b^2 c^2 |g|^3)`` with
    ``g = (x/a^2, y/b^2, z/c^2)``.  The area is a quadrature (trapezoidal in
    ``u``, 128-point Gauss-Legendre in ``sin v``, both spectrally accurate).
    ``"grid"`` is the Fibonacci sphere mapped (as ``"fibonacci"``: *not*
    area-uniform), ``"jittered"`` the jittered Fibonacci sphere mapped,
    ``"random"`` is area-uniform.

    Parameters
    ----------
    a, b, c : float
        Semi-axes along x, y and z, ``> 0`` (any order).
    """

    name = "ellipsoid"

    def __init__(self, a: float = 1.0, b: float = 0.8, c: float = 0.6):
        self.a = _positive("a", a)
        self.b = _positive("b", b)
        self.c = _positive("c", c)
        self.axes = np.array([self.a, self.b, self.c])

    def _params(self):
        return {"a": self.a, "b": self.b, "c": self.c}

    def _semi_axes(self):
        return self.a, self.b, self.c

    def _angle_frame(self, p):
        return p / self.axes

    def position(self, u, v):
        u, v = _as_uv(u, v)
        cv = np.cos(v)
        return _vec(u.size, self.a * cv * np.cos(u), self.b * cv * np.sin(u), self.c * np.sin(v))

    def _gradient(self, u, v):
        """``g = (x/a^2, y/b^2, z/c^2)`` at ``X(u, v)``, shape (n, 3)."""
        return _radial(u, v) / self.axes

    def normal(self, u, v):
        u, v = _as_uv(u, v)
        return _unit(self._gradient(u, v))

    def curvature(self, u, v):
        u, v = _as_uv(u, v)
        g = self._gradient(u, v)
        q = np.linalg.norm(g, axis=1)
        nrm = g / q[:, None]
        e1 = _unit(_vec(u.size, -self.a * np.sin(u), self.b * np.cos(u), 0.0))
        e2 = np.cross(nrm, e1)
        w = 1.0 / self.axes**2  # Hess(F) / 2

        def form(x, y):
            return np.einsum("ij,ij,j->i", x, y, w) / q

        return _curvature_in_frame(e1, e2, form(e1, e1), form(e1, e2), form(e2, e2))

    @_cached_in("_cached_area")
    def area(self):
        # dA = a b c sqrt((1 - s^2) alpha(u) + s^2 / c^2) du ds with s = sin v
        s_nodes, s_weights = np.polynomial.legendre.leggauss(128)
        u = _TWO_PI * np.arange(512) / 512
        alpha = np.cos(u) ** 2 / self.a**2 + np.sin(u) ** 2 / self.b**2
        s2 = s_nodes[:, None] ** 2
        integrand = np.sqrt((1.0 - s2) * alpha[None, :] + s2 / self.c**2)
        return float(self.a * self.b * self.c * _TWO_PI / 512 * (s_weights @ integrand.sum(axis=1)))

    def implicit(self, points):
        """``|p / (a, b, c)| - 1``, shape (n,); Lipschitz ``1 / min(a, b, c)``."""
        p = _as_points(points)
        return np.linalg.norm(p / self.axes, axis=1) - 1.0

    def _implicit_lipschitz(self):
        return 1.0 / float(np.min(self.axes))

    def bounding_box(self):
        return -self.axes.copy(), self.axes.copy()

    def _intersect(self, o, d):
        os_, ds = o / self.axes, d / self.axes
        return _first_quadric_root(_dot(ds, ds), _dot(os_, ds), _dot(os_, os_) - 1.0)


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
        return _radial(u, v)

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
        return _principal_curvature(k1, k2, d1, d2)

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

    def parameters_of(self, points):
        """Angles of ``points``: ``u`` about the z axis, ``v`` about the tube's centre circle.

        Off the surface this is the nearest-point projection onto the torus
        (radial from the centre circle).

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        u, v : ndarray, shape (n,)
        """
        p = _as_points(points)
        rho = np.hypot(p[:, 0], p[:, 1])
        return _longitude(p), _wrap(np.arctan2(p[:, 2], rho - self.r2), 0.0, _TWO_PI)

    def implicit(self, points):
        """Signed distance ``|p - centre circle| - r1``, shape (n,)."""
        p = _as_points(points)
        return np.hypot(np.hypot(p[:, 0], p[:, 1]) - self.r2, p[:, 2]) - self.r1

    def bounding_box(self):
        r = self.r1 + self.r2
        return np.array([-r, -r, -self.r1]), np.array([r, r, self.r1])


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
        return _principal_curvature(k1, k2, _east(u), _vec(u.size, 0.0, 0.0, 1.0), mean=0.5 * k1)

    def area(self):
        return _TWO_PI * self.radius * self.height

    def _from_unit_square(self, t1, t2):
        return _TWO_PI * t2, -0.5 * self.height + self.height * t1

    def parameters_of(self, points):
        """Angle about the z axis and height ``z`` (radial projection; ``v`` not clipped).

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        u, v : ndarray, shape (n,)
        """
        p = _as_points(points)
        return _longitude(p), p[:, 2].copy()

    def implicit(self, points):
        """Signed distance to the infinite cylinder, ``hypot(x, y) - R``, shape (n,)."""
        p = _as_points(points)
        return np.hypot(p[:, 0], p[:, 1]) - self.radius

    def bounding_box(self):
        r, h = self.radius, 0.5 * self.height
        return np.array([-r, -r, -h]), np.array([r, r, h])

    def _intersect(self, o, d):
        h = 0.5 * self.height
        qa = d[:, 0] ** 2 + d[:, 1] ** 2
        qb = o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1]
        qc = o[:, 0] ** 2 + o[:, 1] ** 2 - self.radius**2
        return _first_quadric_root(qa, qb, qc, valid=lambda t: np.abs(o[:, 2] + t * d[:, 2]) <= h)

    def default_viewpoints(self):
        """Three viewpoints around the tube, from the side (see :meth:`Surface.default_viewpoints`).

        Returns
        -------
        ndarray, shape (3, 3)
        """
        lo, hi = self.bounding_box()
        radius = 0.5 * float(np.linalg.norm(hi - lo))
        heights = (0.6, -0.6, 0.0)
        views = [
            (az, math.degrees(math.asin(f * 0.5 * self.height / (r * radius))), r)
            for (az, _, r), f in zip(_AROUND, heights)
        ]
        return _view_positions(views, lo, hi)


# ---------------------------------------------------------------------------
# graphs z = f(x, y)
# ---------------------------------------------------------------------------


class _SquarePatch(Surface):
    """Open patch over the parameter square ``[-size, size]^2``, seen from above.

    What the graphs and the folded square share: the square domain, the
    inverse parametrisation by vertical projection (``u`` from ``x`` by
    :meth:`_u_of_x`, ``v = y``) and the scan viewpoints above the patch.
    """

    closed = False
    periodic = (False, False)

    def _set_size(self, size) -> None:
        """Validate the half-width ``size`` and set the square domain."""
        self.size = _positive("size", size)
        self.domain = ((-self.size, self.size), (-self.size, self.size))

    def _u_of_x(self, x: np.ndarray) -> np.ndarray:
        """The parameter ``u`` of the surface points with coordinate ``x`` (a new array)."""
        raise NotImplementedError

    def parameters_of(self, points):
        """Parameters of ``points`` by vertical projection (not clipped to the square).

        ``(x, y)`` on a :class:`Graph`, ``(x / cos b, y)`` on the
        :class:`FoldedSquare`.

        Parameters
        ----------
        points : array_like, shape (n, 3)

        Returns
        -------
        u, v : ndarray, shape (n,)
        """
        p = _as_points(points)
        return self._u_of_x(p[:, 0]), p[:, 1].copy()

    def default_viewpoints(self):
        """Three viewpoints above the patch, the graph or the folded square's roof.

        See :meth:`Surface.default_viewpoints`.

        Returns
        -------
        ndarray, shape (3, 3)
        """
        return _view_positions(_ABOVE, *self.bounding_box())


class Graph(_SquarePatch):
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
        self._funcs = funcs
        self._set_size(size)
        self.name = str(name)

    def _params(self):
        return {"size": self.size, "name": self.name}

    def _eval(self, label, x, y):
        """The function ``label`` (``"f"``, ``"fx"``, ...) at ``(x, y)``, shape of ``x``."""
        out = np.asarray(self._funcs[label](x, y), dtype=np.float64)
        try:
            return np.broadcast_to(out, x.shape)
        except ValueError:
            raise HeatcurvError(
                f"{label}(x, y) returned shape {out.shape}, expected {x.shape} or a scalar"
            ) from None

    def position(self, u, v):
        u, v = _as_uv(u, v)
        return _vec(u.size, u, v, self._eval("f", u, v))

    def tangents(self, u, v):
        u, v = _as_uv(u, v)
        return (
            _vec(u.size, 1.0, 0.0, self._eval("fx", u, v)),
            _vec(u.size, 0.0, 1.0, self._eval("fy", u, v)),
        )

    def second_derivatives(self, u, v):
        u, v = _as_uv(u, v)
        return tuple(_vec(u.size, 0.0, 0.0, self._eval(k, u, v)) for k in ("fxx", "fxy", "fyy"))

    def _u_of_x(self, x):
        return x.copy()

    def implicit(self, points):
        """``z - f(x, y)``, shape (n,) (positive above the graph)."""
        p = _as_points(points)
        return p[:, 2] - self._eval("f", p[:, 0], p[:, 1])

    @_cached_in("_cached_graph_bounds")
    def _graph_bounds(self):
        """``(G, zmin, zmax)``: a bound of ``|grad f|`` and a z range, on a dense grid."""
        t = np.linspace(-self.size, self.size, 257)
        xx, yy = np.meshgrid(t, t)
        x, y = xx.ravel(), yy.ravel()
        z = self._eval("f", x, y)
        grad = np.hypot(self._eval("fx", x, y), self._eval("fy", x, y))
        big = 1.25 * float(np.max(grad)) + 1e-12  # the grid maximum can miss a peak
        slack = big * math.sqrt(2.0) * (t[1] - t[0]) + 1e-9 * self.size
        return big, float(np.min(z)) - slack, float(np.max(z)) + slack

    def _implicit_lipschitz(self):
        return math.sqrt(1.0 + self._graph_bounds()[0] ** 2)

    def bounding_box(self):
        _, zmin, zmax = self._graph_bounds()
        s = self.size
        return np.array([-s, -s, zmin]), np.array([s, s, zmax])

    def _march_box(self):
        lo, hi = self.bounding_box()
        return lo, hi  # z already has slack; x, y are exactly the border

    @_cached_in("_cached_area")
    def area(self):
        nodes, weights = np.polynomial.legendre.leggauss(200)
        x = self.size * nodes
        xx, yy = np.meshgrid(x, x, indexing="ij")
        w = self.area_element(xx.ravel(), yy.ravel()).reshape(xx.shape)
        return float(self.size**2 * (weights @ w @ weights))


class _CoefficientGraph(Graph):
    """A :class:`Graph` family ``z = f(x, y; a)`` with one real coefficient ``a``.

    Subclasses give ``f`` and its derivatives for a coefficient in
    :meth:`_functions` and pass their parameters and name on to ``__init__``.

    Parameters
    ----------
    a : float
    size : float
    """

    def __init__(self, a: float, size: float, name: str):
        a = _finite("a", a)
        self.a = a
        super().__init__(*self._functions(a), size=size, name=name)

    @staticmethod
    def _functions(a: float) -> tuple[Callable, ...]:
        """``f, fx, fy, fxx, fxy, fyy`` for the coefficient ``a``."""
        raise NotImplementedError

    def _params(self):
        return {"a": self.a, "size": self.size}


class Paraboloid(_CoefficientGraph):
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
        super().__init__(a, size, name="paraboloid")

    @staticmethod
    def _functions(a):
        return (
            lambda x, y: a * (x * x + y * y),
            lambda x, y: 2.0 * a * x,
            lambda x, y: 2.0 * a * y,
            lambda x, y: 2.0 * a,
            lambda x, y: 0.0,
            lambda x, y: 2.0 * a,
        )


class Saddle(_CoefficientGraph):
    """Hyperbolic paraboloid ``z = a (x^2 - y^2)`` over ``[-size, size]^2``.

    Parameters
    ----------
    a : float
    size : float
    """

    name = "saddle"

    def __init__(self, a: float = 0.5, size: float = 1.0):
        super().__init__(a, size, name="saddle")

    @staticmethod
    def _functions(a):
        return (
            lambda x, y: a * (x * x - y * y),
            lambda x, y: 2.0 * a * x,
            lambda x, y: -2.0 * a * y,
            lambda x, y: 2.0 * a,
            lambda x, y: 0.0,
            lambda x, y: -2.0 * a,
        )


class Arch(_CoefficientGraph):
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
        super().__init__(a, size, name="arch")

    @staticmethod
    def _functions(a):
        return (
            lambda x, y: -a * x * x,
            lambda x, y: -2.0 * a * x,
            lambda x, y: 0.0,
            lambda x, y: -2.0 * a,
            lambda x, y: 0.0,
            lambda x, y: 0.0,
        )


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
        def zero(x, y):
            return 0.0

        super().__init__(zero, zero, zero, zero, zero, zero, size=size, name="plane")

    def _params(self):
        return {"size": self.size}

    def area(self):
        return (2.0 * self.size) ** 2


# ---------------------------------------------------------------------------
# folded square (sharp feature)
# ---------------------------------------------------------------------------


class FoldedSquare(_SquarePatch):
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

    def __init__(self, interior_angle: float = 90.0, size: float = 1.0):
        angle = _finite("interior_angle", interior_angle)
        if not 0.0 < angle <= 180.0:
            raise HeatcurvError(
                f"interior_angle must be in (0, 180] degrees, got {interior_angle!r}"
            )
        self.interior_angle = angle
        self._set_size(size)
        self.beta = math.radians(0.5 * (180.0 - angle))

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
        d2 = _vec(u.size, 0.0, 1.0, 0.0)
        every = np.ones(u.shape, dtype=bool)
        d1 = _unit(xu)
        return _principal_curvature(zero.copy(), zero.copy(), d1, d2, mean=zero, umbilic=every)

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

    def _u_of_x(self, x):
        return x / math.cos(self.beta)

    def implicit(self, points):
        """``z + |x| tan b``, shape (n,) (positive above the roof)."""
        p = _as_points(points)
        return p[:, 2] + np.abs(p[:, 0]) * math.tan(self.beta)

    def _implicit_lipschitz(self):
        return 1.0 / math.cos(self.beta)

    def bounding_box(self):
        s = self.size
        x = s * math.cos(self.beta)
        return np.array([-x, -s, -s * math.sin(self.beta)]), np.array([x, s, 0.0])

    def _march_box(self):
        lo, hi = self.bounding_box()
        pad = 1e-6 * float(np.linalg.norm(hi - lo)) + 1e-12
        return lo - np.array([0.0, 0.0, pad]), hi + np.array([0.0, 0.0, pad])


# ---------------------------------------------------------------------------
# registry
# ---------------------------------------------------------------------------

#: Ready-to-use surfaces by name (:class:`Graph` is not listed: it needs ``f``).
SURFACES: dict[str, type[Surface]] = {
    "sphere": Sphere,
    "ellipsoid": Ellipsoid,
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
