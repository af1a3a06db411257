"""Graphs ``z = f(x, y)`` over a square: the general :class:`Graph` and its ready-made family."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from heatcurv.errors import HeatcurvError

from ._util import _as_points, _as_uv, _cached_in, _finite, _vec
from .patches import _SquarePatch


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
