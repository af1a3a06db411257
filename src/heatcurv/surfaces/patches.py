"""Open surfaces with a border: the cylinder, the square patch and the folded square.

:class:`Cylinder` (open tube, closed-form rays); ``_SquarePatch``, the square
parameter domain seen from above that the graphs (:mod:`heatcurv.surfaces.graphs`)
and the folded square share; :class:`FoldedSquare`, the roof with a sharp fold.
"""

from __future__ import annotations

import math

import numpy as np

from heatcurv.errors import HeatcurvError

from ._util import _TWO_PI, _as_points, _as_uv, _east, _finite, _longitude, _positive, _unit, _vec
from .base import Surface
from .curvature import _principal_curvature
from .rays import _first_quadric_root
from .scan import _ABOVE, _AROUND, _view_positions


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
