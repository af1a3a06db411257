"""Surfaces under test and independent checks shared by the tests of heatcurv.surfaces.

Everything here is written independently of the package: the graph functions
are spelled out again, the implicit residuals come from textbook equations.
(No ``__init__.py`` in this directory: the test modules import this one by
name, which pytest's rootdir-relative import makes possible.)
"""

from __future__ import annotations

import math

import numpy as np

from heatcurv import surfaces as hs

# f, fx, fy, fxx, fxy, fyy of the graph cases, written out here independently
GRAPH_FUNCS = {
    "paraboloid": (  # a = 0.7
        lambda x, y: 0.7 * (x * x + y * y),
        lambda x, y: 1.4 * x,
        lambda x, y: 1.4 * y,
        lambda x, y: 1.4 + 0 * x,
        lambda x, y: 0 * x,
        lambda x, y: 1.4 + 0 * x,
    ),
    "saddle": (  # a = 0.5
        lambda x, y: 0.5 * (x * x - y * y),
        lambda x, y: x,
        lambda x, y: -y,
        lambda x, y: 1.0 + 0 * x,
        lambda x, y: 0 * x,
        lambda x, y: -1.0 + 0 * x,
    ),
    "arch": (  # a = 0.5
        lambda x, y: -0.5 * x * x,
        lambda x, y: -x,
        lambda x, y: 0 * x,
        lambda x, y: -1.0 + 0 * x,
        lambda x, y: 0 * x,
        lambda x, y: 0 * x,
    ),
    "plane": tuple(lambda x, y: 0 * x for _ in range(6)),
    # non-polynomial, so that nothing in the graph formulas is trivially exact
    "wavy": (
        lambda x, y: 0.3 * np.sin(2 * x) * np.cos(y) + 0.1 * x * y,
        lambda x, y: 0.6 * np.cos(2 * x) * np.cos(y) + 0.1 * y,
        lambda x, y: -0.3 * np.sin(2 * x) * np.sin(y) + 0.1 * x,
        lambda x, y: -1.2 * np.sin(2 * x) * np.cos(y),
        lambda x, y: -0.6 * np.cos(2 * x) * np.sin(y) + 0.1,
        lambda x, y: -0.3 * np.sin(2 * x) * np.cos(y),
    ),
}


def wavy_graph() -> hs.Graph:
    return hs.Graph(*GRAPH_FUNCS["wavy"], size=1.2, name="wavy")


CASES = {
    "sphere": lambda: hs.Sphere(),
    "sphere_shifted": lambda: hs.Sphere(radius=1.7, centre=(0.3, -0.2, 0.5)),
    "ellipsoid": lambda: hs.Ellipsoid(),
    "ellipsoid_prolate": lambda: hs.Ellipsoid(a=0.7, b=1.3, c=1.9),  # axes in any order
    "torus": lambda: hs.Torus(),
    "torus_thin": lambda: hs.Torus(r1=0.4, r2=1.5),
    "paraboloid": lambda: hs.Paraboloid(a=0.7, size=1.3),
    "saddle": lambda: hs.Saddle(),
    "arch": lambda: hs.Arch(),
    "plane": lambda: hs.Plane(size=2.0),
    "cylinder": lambda: hs.Cylinder(radius=0.8, height=3.0),
    "folded_90": lambda: hs.FoldedSquare(),
    "folded_60": lambda: hs.FoldedSquare(interior_angle=60.0, size=1.5),
    "wavy": wavy_graph,
}


GRAPH_CASES = ["paraboloid", "saddle", "arch", "plane", "wavy"]


def random_params(surf, n=50, seed=0):
    """Parameters away from the border, the fold and the sphere's poles."""
    rng = np.random.default_rng(seed)
    (u0, u1), (v0, v1) = surf.domain
    m = 0.02 * min(u1 - u0, v1 - v0)
    if isinstance(surf, (hs.Sphere, hs.Ellipsoid)):
        v0, v1 = -1.3, 1.3  # the latitude parametrisation is singular at the poles
    u = rng.uniform(u0 + m, u1 - m, n)
    v = rng.uniform(v0 + m, v1 - m, n)
    if isinstance(surf, hs.FoldedSquare):
        # FD stencils reach 2 * 5e-3 = 0.01; stay 0.05 away from the fold
        u = np.sign(u) * np.maximum(np.abs(u), 0.05) + (u == 0) * 0.05
    return u, v


def residual(case, surf, p, strict=True):
    """Implicit-equation residual, written independently of the module.

    ``strict`` also asserts that the points lie within the open surfaces'
    border (exactly; with ``strict=False`` to 1e-12).
    """
    if not strict:
        return _residual_formula(case, surf, p)
    x, y, z = p.T
    if isinstance(surf, hs.Sphere):
        return np.linalg.norm(p - surf.centre, axis=1) - surf.radius
    if isinstance(surf, hs.Ellipsoid):
        return (x / surf.a) ** 2 + (y / surf.b) ** 2 + (z / surf.c) ** 2 - 1
    if isinstance(surf, hs.Torus):
        return (np.hypot(x, y) - surf.r2) ** 2 + z**2 - surf.r1**2
    if isinstance(surf, hs.Cylinder):
        assert np.all(np.abs(z) <= surf.height / 2)
        return np.hypot(x, y) - surf.radius
    if isinstance(surf, hs.FoldedSquare):
        b = math.radians((180 - surf.interior_angle) / 2)
        assert np.all(np.abs(y) <= surf.size)
        assert np.all(np.abs(x) <= surf.size * math.cos(b) + 1e-15)
        return z + np.abs(x) * math.tan(b)
    assert np.all(np.abs(x) <= surf.size) and np.all(np.abs(y) <= surf.size)
    return z - GRAPH_FUNCS[case][0](x, y)


def _residual_formula(case, surf, p):
    """The formulas of :func:`residual`, border checked to 1e-12 only."""
    x, y, z = p.T
    tol = 1e-12
    if isinstance(surf, hs.Sphere):
        return np.linalg.norm(p - surf.centre, axis=1) - surf.radius
    if isinstance(surf, hs.Ellipsoid):
        return (x / surf.a) ** 2 + (y / surf.b) ** 2 + (z / surf.c) ** 2 - 1
    if isinstance(surf, hs.Torus):
        return (np.hypot(x, y) - surf.r2) ** 2 + z**2 - surf.r1**2
    if isinstance(surf, hs.Cylinder):
        assert np.all(np.abs(z) <= surf.height / 2 + tol)
        return np.hypot(x, y) - surf.radius
    if isinstance(surf, hs.FoldedSquare):
        b = math.radians((180 - surf.interior_angle) / 2)
        assert np.all(np.abs(y) <= surf.size + tol)
        assert np.all(np.abs(x) <= surf.size * math.cos(b) + tol)
        return z + np.abs(x) * math.tan(b)
    assert np.all(np.abs(x) <= surf.size + tol) and np.all(np.abs(y) <= surf.size + tol)
    return z - GRAPH_FUNCS[case][0](x, y)


def in_domain(surf, p):
    """Mask of 3-D points whose vertical / axial position is within the open surface's border."""
    x, y, z = p.T
    if surf.closed:
        return np.ones(len(p), dtype=bool)
    if isinstance(surf, hs.Cylinder):
        return np.abs(z) <= surf.height / 2
    if isinstance(surf, hs.FoldedSquare):
        b = math.radians((180 - surf.interior_angle) / 2)
        return (np.abs(x) <= surf.size * math.cos(b)) & (np.abs(y) <= surf.size)
    return (np.abs(x) <= surf.size) & (np.abs(y) <= surf.size)


def binomial_check(frac, p, n):
    # 5 binomial standard deviations: a false failure has probability < 1e-6
    assert abs(frac - p) < 5 * math.sqrt(p * (1 - p) / n), (frac, p)


def segment_signs(case, surf, o, p, k=1500, end=1 - 1e-4):
    """Independent residual signs at k points on each segment o -> p (shape (m, k)), 0 off the domain."""
    f = np.linspace(0, end, k)
    q = o[:, None, :] + f[None, :, None] * (p - o)[:, None, :]
    flat = q.reshape(-1, 3)
    (u0, u1), (v0, v1) = surf.domain
    inner = surf.position([0.5 * (u0 + u1)], [0.5 * (v0 + v1)])  # stand-in for off-domain points
    r = _residual_formula(case, surf, np.where(in_domain(surf, flat)[:, None], flat, inner))
    return np.where(in_domain(surf, flat), np.sign(r), 0.0).reshape(q.shape[:2])
