"""Closed surfaces: sphere, ellipsoid and ring torus, with outward normals."""

from __future__ import annotations

import math

import numpy as np

from heatcurv.errors import HeatcurvError

from ._util import (
    _TWO_PI,
    _as_points,
    _as_uv,
    _cached_in,
    _dot,
    _east,
    _longitude,
    _positive,
    _radial,
    _unit,
    _vec,
    _wrap,
)
from .base import Surface
from .curvature import _curvature_in_frame, _principal_curvature
from .rays import _first_quadric_root


class _LatitudeLongitude(Surface):
    """Closed surface parametrised like the sphere, by longitude and latitude.

    ``X(u, v) = centre + (a cos v cos u, b cos v sin u, c sin v)`` with the
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
    """Sphere of radius ``R`` about ``centre``, outward normals.

    ``X(u, v) = centre + R (cos v cos u, cos v sin u, sin v)`` with longitude
    ``u`` in ``[0, 2 pi)`` and latitude ``v`` in ``[-pi/2, pi/2]``.
    Curvatures ``k1 = k2 = mean = 1/R``, ``gaussian = 1/R^2``; every point is
    umbilic (``d1`` is the east direction, ``d2`` north).  ``"grid"`` sampling
    gives the Fibonacci sphere (a latitude-longitude grid clusters at the poles).

    Parameters
    ----------
    radius : float
        ``R > 0``.
    centre : array_like, shape (3,), optional
        The centre; default the origin.

    Attributes
    ----------
    radius : float
    centre : ndarray, shape (3,)
    """

    name = "sphere"

    def __init__(self, radius: float = 1.0, centre=None):
        self.radius = _positive("radius", radius)
        if centre is None:
            centre = (0.0, 0.0, 0.0)
        c = np.asarray(centre, dtype=np.float64)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise HeatcurvError(f"centre must be 3 finite numbers, got {centre!r}")
        self.centre = c

    def _params(self):
        return {"radius": self.radius, "centre": tuple(self.centre.tolist())}

    def _semi_axes(self):
        return self.radius, self.radius, self.radius

    def _angle_frame(self, p):
        return p - self.centre

    def position(self, u, v):
        u, v = _as_uv(u, v)
        return self.centre + self.radius * _radial(u, v)

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
        """Signed distance ``|p - centre| - R``, shape (n,)."""
        p = _as_points(points)
        return np.linalg.norm(p - self.centre, axis=1) - self.radius

    def bounding_box(self):
        return self.centre - self.radius, self.centre + self.radius

    def _intersect(self, o, d):
        rel = o - self.centre
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
