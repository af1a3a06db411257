"""Tests of heatcurv.surfaces: exact geometry checked against finite differences.

Every exact quantity is verified independently of the module's own derivative
code: the derivatives of the parametrisation are recomputed here from
``position`` alone by 4th-order central finite differences, the normal is
oriented by an independent geometric test, and the shape operator
``S = -I^{-1} II`` is diagonalised with ``numpy.linalg.eig``.

Finite-difference error budget (positions are O(1..3)):

* first derivatives, 4th-order stencil, h = 1e-3: truncation ~ h^4/30 |X^(5)|
  ~ 1e-13, rounding ~ 1.5 eps |X| / h ~ 1e-12;
* second derivatives (incl. the tensor-product mixed one), h = 5e-3:
  truncation ~ h^4/90 |X^(6)| <~ 1.5e-10 (|X^(6)| <~ 20 for the wavy graph),
  rounding ~ 5 eps |X| / h^2 ~ 1.5e-10.

So FD curvatures are good to ~1e-9; we assert 1e-7 (relative to max(1, |k|)),
and principal directions (error ~ dS / gap) to 1e-6 where the gap k1-k2 > 1e-2.
Measured worst cases over all surfaces: curvatures 2.6e-10, directions 1e-10,
normals 6e-13, so the assertions keep a margin of a few hundred.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.spatial import cKDTree

from heatcurv import surfaces as hs
from heatcurv.errors import HeatcurvError

# ---------------------------------------------------------------------------
# surfaces under test
# ---------------------------------------------------------------------------


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
    "sphere_shifted": lambda: hs.Sphere(radius=1.7, center=(0.3, -0.2, 0.5)),
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
    if isinstance(surf, hs.Sphere):
        v0, v1 = -1.3, 1.3  # the latitude parametrisation is singular at the poles
    u = rng.uniform(u0 + m, u1 - m, n)
    v = rng.uniform(v0 + m, v1 - m, n)
    if isinstance(surf, hs.FoldedSquare):
        # FD stencils reach 2 * 5e-3 = 0.01; stay 0.05 away from the fold
        u = np.sign(u) * np.maximum(np.abs(u), 0.05) + (u == 0) * 0.05
    return u, v


def outward_reference(surf, p):
    """Independent orientation reference vector for each surface (shape (n, 3))."""
    if isinstance(surf, hs.Sphere):
        return p - surf.center
    if isinstance(surf, hs.Torus):
        rho = np.hypot(p[:, 0], p[:, 1])
        centre = surf.r2 * np.column_stack([p[:, 0] / rho, p[:, 1] / rho, 0 * rho])
        return p - centre
    if isinstance(surf, hs.Cylinder):
        return np.column_stack([p[:, 0], p[:, 1], 0 * p[:, 0]])
    return np.tile([0.0, 0.0, 1.0], (len(p), 1))  # graphs, plane, fold: upward


H1, H2 = 1e-3, 5e-3
C1 = {-2: 1 / 12, -1: -8 / 12, 1: 8 / 12, 2: -1 / 12}
C2 = {-2: -1 / 12, -1: 16 / 12, 0: -30 / 12, 1: 16 / 12, 2: -1 / 12}


def fd_geometry(surf, u, v):
    """FD derivatives, oriented normal and shape operator from ``position`` only."""
    P = surf.position
    xu = sum(c * P(u + k * H1, v) for k, c in C1.items()) / H1
    xv = sum(c * P(u, v + k * H1) for k, c in C1.items()) / H1
    xuu = sum(c * P(u + k * H2, v) for k, c in C2.items()) / H2**2
    xvv = sum(c * P(u, v + k * H2) for k, c in C2.items()) / H2**2
    xuv = sum(
        ci * cj * P(u + i * H2, v + j * H2) for i, ci in C1.items() for j, cj in C1.items()
    ) / H2**2
    n = np.cross(xu, xv)
    n /= np.linalg.norm(n, axis=1)[:, None]
    ref = outward_reference(surf, P(u, v))
    s = np.einsum("ij,ij->i", n, ref)
    # the reference must be far from tangent for the orientation to mean anything
    assert np.all(np.abs(s) > 0.1 * np.linalg.norm(ref, axis=1))
    n *= np.sign(s)[:, None]
    first = np.stack(
        [
            np.stack([np.einsum("ij,ij->i", xu, xu), np.einsum("ij,ij->i", xu, xv)], -1),
            np.stack([np.einsum("ij,ij->i", xv, xu), np.einsum("ij,ij->i", xv, xv)], -1),
        ],
        -2,
    )
    second = np.stack(
        [
            np.stack([np.einsum("ij,ij->i", xuu, n), np.einsum("ij,ij->i", xuv, n)], -1),
            np.stack([np.einsum("ij,ij->i", xuv, n), np.einsum("ij,ij->i", xvv, n)], -1),
        ],
        -2,
    )
    shape = -np.linalg.solve(first, second)
    evals, evecs = np.linalg.eig(shape)
    evals, evecs = evals.real, evecs.real
    order = np.argsort(-evals, axis=1)
    evals = np.take_along_axis(evals, order, 1)
    evecs = np.take_along_axis(evecs, order[:, None, :], 2)
    dirs = [
        evecs[:, 0, j, None] * xu + evecs[:, 1, j, None] * xv for j in range(2)
    ]
    dirs = [d / np.linalg.norm(d, axis=1)[:, None] for d in dirs]
    return dict(
        xu=xu, xv=xv, xuu=xuu, xuv=xuv, xvv=xvv, n=n,
        k1=evals[:, 0], k2=evals[:, 1],
        mean=0.5 * np.trace(shape, axis1=1, axis2=2),
        gaussian=np.linalg.det(second) / np.linalg.det(first),
        d1=dirs[0], d2=dirs[1],
    )


def same_up_to_sign(a, b):
    return np.minimum(np.linalg.norm(a - b, axis=1), np.linalg.norm(a + b, axis=1))


# ---------------------------------------------------------------------------
# exact geometry against finite differences
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("case", sorted(CASES))
def test_tangents_normals_and_second_derivatives_match_fd(case):
    surf = CASES[case]()
    u, v = random_params(surf)
    fd = fd_geometry(surf, u, v)
    xu, xv = surf.tangents(u, v)
    xuu, xuv, xvv = surf.second_derivatives(u, v)
    # first derivatives: FD error ~1e-12 (see module docstring)
    assert np.max(np.abs(xu - fd["xu"])) < 1e-9
    assert np.max(np.abs(xv - fd["xv"])) < 1e-9
    # second derivatives: FD error ~3e-10
    for exact, key in ((xuu, "xuu"), (xuv, "xuv"), (xvv, "xvv")):
        assert np.max(np.abs(exact - fd[key])) < 1e-7
    n = surf.normal(u, v)
    assert n.dtype == np.float64 and n.shape == (50, 3)
    assert np.max(np.abs(n - fd["n"])) < 1e-9  # same orientation, not just same line


@pytest.mark.parametrize("case", sorted(CASES))
def test_curvature_matches_fd_shape_operator(case):
    surf = CASES[case]()
    u, v = random_params(surf)
    fd = fd_geometry(surf, u, v)
    c = surf.curvature(u, v)
    for key in ("k1", "k2", "mean", "gaussian"):
        exact = getattr(c, key)
        scale = np.maximum(1.0, np.abs(exact))
        assert exact.shape == (50,) and exact.dtype == np.float64
        assert np.max(np.abs(exact - fd[key]) / scale) < 1e-7, key
    gap = fd["k1"] - fd["k2"]
    ok = gap > 1e-2
    assert not np.any(c.umbilic & ok)
    if np.any(ok):
        assert np.max(same_up_to_sign(c.d1[ok], fd["d1"][ok])) < 1e-6
        assert np.max(same_up_to_sign(c.d2[ok], fd["d2"][ok])) < 1e-6
    umbilic_surface = case.startswith(("sphere", "plane", "folded"))
    assert np.all(c.umbilic) == umbilic_surface
    assert np.any(ok) == (not umbilic_surface)


@pytest.mark.parametrize("case", sorted(CASES))
def test_generic_formula_agrees_with_closed_form(case):
    surf = CASES[case]()
    u, v = random_params(surf, seed=1)
    a = surf.curvature(u, v)
    b = surf.curvature_from_derivatives(u, v)
    for key in ("k1", "k2", "mean", "gaussian"):
        # both exact up to rounding
        assert np.allclose(getattr(a, key), getattr(b, key), rtol=1e-12, atol=1e-12), key
    ok = ~a.umbilic
    assert np.array_equal(a.umbilic, b.umbilic)
    assert np.all(same_up_to_sign(a.d1[ok], b.d1[ok]) < 1e-12)


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("sampler", hs.SAMPLERS)
def test_frame_is_orthonormal_and_right_handed(case, sampler):
    surf = CASES[case]()
    smp = surf.sample(400, sampler=sampler, seed=3)  # includes border, fold, near-poles
    n, d1, d2 = smp.normals, smp.d1, smp.d2
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-14)
    assert np.allclose(np.linalg.norm(d1, axis=1), 1.0, atol=1e-14)
    assert np.allclose(np.linalg.norm(d2, axis=1), 1.0, atol=1e-14)
    assert np.max(np.abs(np.einsum("ij,ij->i", d1, n))) < 1e-14
    assert np.max(np.abs(np.einsum("ij,ij->i", d2, n))) < 1e-14
    assert np.max(np.abs(np.cross(d1, d2) - n)) < 1e-14
    assert np.all(smp.k1 >= smp.k2)
    assert np.allclose(smp.mean, 0.5 * (smp.k1 + smp.k2), rtol=1e-14, atol=1e-15)
    assert np.allclose(smp.gaussian, smp.k1 * smp.k2, rtol=1e-14, atol=1e-15)
    tol = 1e-9 * np.maximum(1.0, np.maximum(np.abs(smp.k1), np.abs(smp.k2)))
    assert np.array_equal(smp.umbilic, smp.k1 - smp.k2 <= tol)


def test_sphere_exact_values():
    surf = hs.Sphere(radius=2.5)
    smp = surf.sample(500, "random", seed=0)
    assert np.all(smp.mean == 1 / 2.5)  # exactly, not approximately
    assert np.all(smp.k1 == 1 / 2.5) and np.all(smp.k2 == 1 / 2.5)
    assert np.all(smp.gaussian == (1 / 2.5) ** 2)  # = k1 * k2 (1/R^2 may round differently)
    assert np.all(smp.umbilic)
    # the exact normal is the radial direction, also at the poles
    n = surf.normal([0.3, 1.0], [math.pi / 2, -math.pi / 2])
    assert np.allclose(n, [[0, 0, 1], [0, 0, -1]], atol=1e-15)


@pytest.mark.parametrize("r1, r2", [(1.0, 2.3701), (0.4, 1.5)])
def test_torus_textbook_formulas(r1, r2):
    surf = hs.Torus(r1=r1, r2=r2)
    u, v = np.meshgrid(np.linspace(0, 6, 13), np.linspace(0, 6.2, 17))
    u, v = u.ravel(), v.ravel()
    c = surf.curvature(u, v)
    k2 = np.cos(v) / (r2 + r1 * np.cos(v))
    assert np.allclose(c.k1, 1 / r1, rtol=1e-15)
    assert np.allclose(c.k2, k2, rtol=1e-14, atol=1e-15)
    assert np.allclose(c.gaussian, np.cos(v) / (r1 * (r2 + r1 * np.cos(v))), rtol=1e-14, atol=1e-15)
    # outer equator: both curvatures positive (sphere-like), inner equator: saddle
    out = surf.curvature([0.0], [0.0])
    inn = surf.curvature([0.0], [math.pi])
    assert out.k2[0] == pytest.approx(1 / (r2 + r1)) and out.gaussian[0] > 0
    assert inn.k2[0] == pytest.approx(-1 / (r2 - r1)) and inn.gaussian[0] < 0


@pytest.mark.parametrize("case", GRAPH_CASES)
def test_graph_monge_formulas(case):
    surf = CASES[case]()
    u, v = random_params(surf, n=200, seed=5)
    _, fx, fy, fxx, fxy, fyy = (g(u, v) for g in GRAPH_FUNCS[case])
    w2 = 1 + fx**2 + fy**2
    mean = -((1 + fy**2) * fxx - 2 * fx * fy * fxy + (1 + fx**2) * fyy) / (2 * w2**1.5)
    gauss = (fxx * fyy - fxy**2) / w2**2
    c = surf.curvature(u, v)
    assert np.allclose(c.mean, mean, rtol=1e-13, atol=1e-14)
    assert np.allclose(c.gaussian, gauss, rtol=1e-12, atol=1e-14)


def test_curvature_signs_and_special_values():
    # upward-opening paraboloid bends toward its upward normal: negative, -2a
    c = hs.Paraboloid(a=0.5).curvature([0.0], [0.0])
    assert c.k1[0] == pytest.approx(-1.0) and c.k2[0] == pytest.approx(-1.0) and c.umbilic[0]
    c = hs.Saddle(a=0.5).curvature([0.0], [0.0])
    assert (c.k1[0], c.k2[0], c.gaussian[0]) == pytest.approx((1.0, -1.0, -1.0))
    assert np.allclose(np.abs(c.d1[0]), [0, 1, 0])  # k1 = +2a along y
    x = np.linspace(-1, 1, 11)
    c = hs.Arch(a=0.5).curvature(x, 0 * x)
    assert np.allclose(c.k1, 1.0 / (1 + x**2) ** 1.5, rtol=1e-14)
    assert np.all(c.k2 == 0) and np.all(c.gaussian == 0)
    c = hs.Cylinder(radius=0.8).curvature([0.3], [0.1])
    assert (c.k1[0], c.k2[0], c.mean[0]) == pytest.approx((1.25, 0.0, 0.625))
    assert np.allclose(c.d2, [[0, 0, 1]])


# ---------------------------------------------------------------------------
# areas
# ---------------------------------------------------------------------------


def test_closed_form_areas():
    assert hs.Sphere(radius=1.7).area() == pytest.approx(4 * math.pi * 1.7**2, rel=1e-15)
    assert hs.Torus(r1=1.0, r2=2.3701).area() == pytest.approx(4 * math.pi**2 * 2.3701, rel=1e-15)
    cyl = hs.Cylinder(radius=0.8, height=3.0)
    assert cyl.area() == pytest.approx(2 * math.pi * 0.8 * 3.0, rel=1e-15)
    assert hs.Plane(size=2.0).area() == 16.0
    assert hs.FoldedSquare(interior_angle=60, size=1.5).area() == 9.0
    # arch: 2 s * int_{-s}^{s} sqrt(1 + k^2 x^2) dx, k = 2a
    a, s = 0.5, 1.0
    k = 2 * a
    exact = 2 * s * (s * math.sqrt(1 + k * k * s * s) + math.asinh(k * s) / k)
    assert hs.Arch(a=a, size=s).area() == pytest.approx(exact, rel=1e-13)


@pytest.mark.parametrize("case", GRAPH_CASES)
def test_graph_area_against_dblquad_of_fd_area_element(case):
    surf = CASES[case]()
    s = surf.size
    h = 1e-5  # central FD: truncation ~h^2 |X'''| ~1e-10, rounding ~eps/h ~1e-11

    def element(y, x):
        p = surf.position([x + h, x - h, x, x], [y, y, y + h, y - h])
        xu = (p[0] - p[1]) / (2 * h)
        xv = (p[2] - p[3]) / (2 * h)
        return float(np.linalg.norm(np.cross(xu, xv)))

    ref, err = integrate.dblquad(element, -s, s, -s, s, epsabs=0, epsrel=1e-11)
    assert surf.area() == pytest.approx(ref, rel=1e-8)


# ---------------------------------------------------------------------------
# samplers
# ---------------------------------------------------------------------------


def residual(case, surf, p):
    """Implicit-equation residual, written independently of the module."""
    x, y, z = p.T
    if isinstance(surf, hs.Sphere):
        return np.linalg.norm(p - surf.center, axis=1) - surf.radius
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


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("sampler", hs.SAMPLERS)
def test_sampler_counts_and_points_on_surface(case, sampler):
    surf = CASES[case]()
    n = 1000
    smp = surf.sample(n, sampler=sampler, seed=11)
    m = len(smp)
    if sampler in ("fibonacci", "random") or isinstance(surf, hs.Sphere):
        assert m == n
    elif isinstance(surf, (hs.Graph, hs.FoldedSquare)):
        assert m == round(math.sqrt(n)) ** 2
    else:
        assert abs(m - n) <= 0.05 * n
    assert smp.sampler == sampler and smp.noise == 0.0 and smp.sigma == 0.0
    for name in ("points", "clean_points", "normals", "d1", "d2"):
        arr = getattr(smp, name)
        assert arr.shape == (m, 3) and arr.dtype == np.float64
    for name in ("u", "v", "mean", "gaussian", "k1", "k2", "border_distance", "feature_distance"):
        arr = getattr(smp, name)
        assert arr.shape == (m,) and arr.dtype == np.float64
    assert smp.umbilic.dtype == bool and smp.umbilic.shape == (m,)
    assert np.array_equal(smp.points, smp.clean_points)
    assert np.max(np.abs(residual(case, surf, smp.clean_points))) < 1e-12
    assert np.array_equal(smp.clean_points, surf.position(smp.u, smp.v))
    assert np.array_equal(smp.normals, surf.normal(smp.u, smp.v))
    assert smp.total_area == surf.area()
    (u0, u1), (v0, v1) = surf.domain
    assert np.all((smp.u >= u0) & (smp.u <= u1) & (smp.v >= v0) & (smp.v <= v1))
    if surf.periodic[0]:
        assert np.all(smp.u < u1)
    if surf.periodic[1]:
        assert np.all(smp.v < v1)
    # no two points coincide (seams are not duplicated); random points may
    # legitimately come close, so only the lattice-based samplers are checked
    if sampler != "random":
        d, _ = cKDTree(smp.clean_points).query(smp.clean_points, 2)
        assert d[:, 1].min() > 1e-3


def _binomial_check(frac, p, n):
    # 5 binomial standard deviations: a false failure has probability < 1e-6
    assert abs(frac - p) < 5 * math.sqrt(p * (1 - p) / n), (frac, p)


def test_random_is_area_uniform_sphere():
    n = 20000
    z = hs.Sphere().sample(n, "random", seed=1).clean_points[:, 2]
    _binomial_check(np.mean(z > 0.5), 0.25, n)  # Archimedes: cap area fraction (1-0.5)/2
    # chi-square over 10 equal-area z bands; 99.99 % quantile of chi2(9) is 33.7
    counts = np.histogram(z, bins=np.linspace(-1, 1, 11))[0]
    chi2 = np.sum((counts - n / 10) ** 2 / (n / 10))
    assert chi2 < 33.7


def test_random_is_area_uniform_torus():
    r1, r2, n = 1.0, 2.3701, 20000
    smp = hs.Torus(r1=r1, r2=r2).sample(n, "random", seed=2)
    outer = np.hypot(smp.clean_points[:, 0], smp.clean_points[:, 1]) > r2
    # outer half of the tube: int_{-pi/2}^{pi/2} (r2 + r1 cos v) dv / (2 pi r2);
    # 0.634 here against 0.5 for parameter-uniform points (~40 std apart)
    _binomial_check(np.mean(outer), 0.5 + r1 / (math.pi * r2), n)


def test_random_is_area_uniform_paraboloid():
    a, n = 0.7, 20000
    smp = hs.Paraboloid(a=a, size=1.0).sample(n, "random", seed=3)
    x, y = smp.clean_points[:, 0], smp.clean_points[:, 1]
    inside = (np.abs(x) < 0.5) & (np.abs(y) < 0.5)
    g, w = np.polynomial.legendre.leggauss(60)

    def area(s):  # tensor Gauss-Legendre of sqrt(1 + 4 a^2 (x^2 + y^2)) on [-s, s]^2
        xx, yy = np.meshgrid(s * g, s * g)
        return s * s * w @ np.sqrt(1 + 4 * a * a * (xx**2 + yy**2)) @ w

    p = area(0.5) / area(1.0)  # ~0.20, against 0.25 for parameter-uniform points
    assert abs(p - 0.25) > 0.03
    _binomial_check(np.mean(inside), p, n)


def test_fibonacci_sphere_is_nearly_uniform():
    for n in (500, 5000):
        p = hs.Sphere().sample(n, "fibonacci").points
        d, _ = cKDTree(p).query(p, 2)
        d = d[:, 1]
        # measured max/min nearest-neighbour ratio ~1.14 for n = 500 .. 20000
        assert d.max() / d.min() < 1.2
        # spacing ~ sqrt(4 pi / n): measured d * sqrt(n) in [3.09, 3.53]
        assert 3.0 < d.min() * math.sqrt(n) and d.max() * math.sqrt(n) < 3.6
        # z is exactly stratified: any z band holds its area fraction to within 1/n
        assert abs(np.mean(p[:, 2] > 0.3) - 0.35) <= 1.0 / n
    grid, fib = hs.Sphere().sample(700, "grid"), hs.Sphere().sample(700, "fibonacci")
    assert np.array_equal(grid.points, fib.points)  # "grid" on the sphere is Fibonacci


def test_fibonacci_torus_and_cylinder_are_area_preserving():
    r1, r2, n = 1.0, 2.3701, 4000
    p = hs.Torus(r1=r1, r2=r2).sample(n, "fibonacci").clean_points
    outer = np.hypot(p[:, 0], p[:, 1]) > r2
    # the tube angle is the inverse CDF of the stratified coordinate, so the
    # outer half (two CDF intervals) holds its area fraction to within 2 points
    assert abs(np.mean(outer) - (0.5 + r1 / (math.pi * r2))) <= 2.0 / n
    upper_outer = outer & (p[:, 2] > 0)
    assert abs(np.mean(upper_outer) - (0.25 + r1 / (2 * math.pi * r2))) <= 2.0 / n
    z = hs.Cylinder(height=2.0).sample(n, "fibonacci").clean_points[:, 2]
    assert abs(np.mean(z > 0.4) - 0.3) <= 1.0 / n


def test_grid_layout():
    surf = hs.Paraboloid()
    smp = surf.sample(1000, "grid")
    assert len(smp) == 32 * 32
    assert np.array_equal(np.unique(smp.u), np.linspace(-1, 1, 32))  # border included
    torus = hs.Torus(r1=1.0, r2=2.3701)
    smp = torus.sample(4000, "grid")
    nu, nv = len(np.unique(smp.u)), len(np.unique(smp.v))
    assert nu * nv == len(smp)
    # nearly square cells: spacing along the centre circle vs around the tube
    ratio = (2 * math.pi * torus.r2 / nu) / (2 * math.pi * torus.r1 / nv)
    assert 0.95 < ratio < 1.05
    cyl = hs.Cylinder(radius=1.0, height=2.0)
    smp = cyl.sample(2000, "grid")
    nu, nv = len(np.unique(smp.u)), len(np.unique(smp.v))
    assert 0.9 < (2 * math.pi / nu) / (2.0 / (nv - 1)) < 1.1
    assert np.isclose(smp.v.min(), -1) and np.isclose(smp.v.max(), 1)


@pytest.mark.parametrize("case", ["torus", "cylinder", "wavy", "folded_90"])
def test_jittered_stays_within_quarter_cell(case):
    surf = CASES[case]()
    grid = surf.sample(900, "grid")
    jit = surf.sample(900, "jittered", seed=4)
    assert len(jit) == len(grid)
    for axis, name in enumerate("uv"):
        g, j = getattr(grid, name), getattr(jit, name)
        (t0, t1) = surf.domain[axis]
        vals = np.unique(g)
        step = (t1 - t0) / len(vals) if surf.periodic[axis] else vals[1] - vals[0]
        diff = j - g
        if surf.periodic[axis]:
            period = t1 - t0
            diff = (diff + period / 2) % period - period / 2
        assert np.max(np.abs(diff)) <= 0.25 * step + 1e-12
        assert np.max(np.abs(diff)) > 0.2 * step  # really jittered
        assert np.all((j >= t0) & (j <= t1))


def test_jittered_sphere():
    n = 2000
    fib = hs.Sphere().sample(n, "fibonacci")
    jit = hs.Sphere().sample(n, "jittered", seed=0)
    d = np.linalg.norm(jit.points - fib.points, axis=1)
    # each point moves by at most 0.25 cell (side sqrt(4 pi / n)) along east and
    # north, and the projection back onto the sphere only shortens the move
    cell = math.sqrt(4 * math.pi / n)
    assert d.max() <= 0.25 * math.sqrt(2) * cell + 1e-12
    assert d.max() > 0.25 * cell  # really jittered
    assert np.allclose(np.linalg.norm(jit.points, axis=1), 1.0, atol=1e-15)
    # still well spread: Fibonacci NN distance >= 3.09 / sqrt(n) minus twice the move
    nn = cKDTree(jit.points).query(jit.points, 2)[0][:, 1]
    assert nn.min() > 0.3 / math.sqrt(n)
    # and the jittered set stays area-uniform (equal-area z halves, binomial 5 std)
    _binomial_check(np.mean(jit.points[:, 2] > 0), 0.5, n)


@pytest.mark.parametrize("case", ["sphere", "torus", "saddle", "folded_90"])
def test_noise_sigma(case):
    surf = CASES[case]()
    noisy = surf.sample(20000, "fibonacci", noise=0.01, seed=5)
    clean = surf.sample(20000, "fibonacci")
    diag = np.linalg.norm(noisy.clean_points.max(0) - noisy.clean_points.min(0))
    assert noisy.sigma == pytest.approx(0.01 * diag, rel=1e-15)
    e = noisy.points - noisy.clean_points
    # 60000 Gaussian values: the sample std has relative std 1/sqrt(2 * 60000) ~ 0.3 %
    assert np.std(e) == pytest.approx(noisy.sigma, rel=0.015)
    # isotropic: each coordinate on its own (20000 values, rel. std 0.5 %)
    assert np.allclose(np.std(e, axis=0), noisy.sigma, rtol=0.03)
    assert np.all(np.abs(np.mean(e, axis=0)) < 5 * noisy.sigma / math.sqrt(20000))
    # exact values are those of the clean points
    for name in ("clean_points", "normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "u", "v"):
        assert np.array_equal(getattr(noisy, name), getattr(clean, name))


@pytest.mark.parametrize("sampler", hs.SAMPLERS)
def test_seed_reproducibility(sampler):
    surf = hs.Torus()
    a = surf.sample(500, sampler, noise=0.02, seed=123)
    b = surf.sample(500, sampler, noise=0.02, seed=123)
    c = surf.sample(500, sampler, noise=0.02, seed=124)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.u, b.u)
    assert not np.array_equal(a.points, c.points)
    if sampler in ("random", "jittered"):
        assert not np.array_equal(a.clean_points, c.clean_points)
    else:  # deterministic layouts
        assert np.array_equal(a.clean_points, c.clean_points)


def test_errors():
    surf = hs.Sphere()
    with pytest.raises(HeatcurvError, match="grid, fibonacci, random, jittered"):
        surf.sample(100, "poisson")
    for bad in (3, 0, -5):
        with pytest.raises(HeatcurvError, match="at least 4"):
            surf.sample(bad)
    with pytest.raises(HeatcurvError):
        surf.sample(10.5)
    with pytest.raises(HeatcurvError):
        surf.sample(100, noise=-0.1)
    with pytest.raises(HeatcurvError):
        surf.sample(100, noise=float("nan"))
    with pytest.raises(HeatcurvError, match="sphere.*torus|torus.*sphere"):
        hs.get("klein_bottle")
    with pytest.raises(HeatcurvError):
        hs.get("sphere", radius=-1)
    with pytest.raises(HeatcurvError):
        hs.get("sphere", radus=1)
    with pytest.raises(HeatcurvError):
        hs.Torus(r1=2.0, r2=1.0)
    with pytest.raises(HeatcurvError):
        hs.FoldedSquare(interior_angle=0)
    with pytest.raises(HeatcurvError):
        hs.FoldedSquare(interior_angle=200)
    with pytest.raises(HeatcurvError):
        surf.position([0.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(HeatcurvError):
        surf.position([np.nan], [0.0])
    assert issubclass(HeatcurvError, ValueError)


def test_registry():
    assert set(hs.SURFACES) == {
        "sphere", "torus", "paraboloid", "saddle", "arch", "plane", "cylinder", "folded_square",
    }
    for name, cls in hs.SURFACES.items():
        surf = hs.get(name)
        assert isinstance(surf, cls) and surf.name == name == cls.name
        assert isinstance(surf, hs.Surface)
        assert surf.closed == (name in ("sphere", "torus"))
    assert isinstance(hs.get("Folded-Square", interior_angle=120), hs.FoldedSquare)
    assert hs.get("torus", r1=0.5, r2=2.0).r1 == 0.5
    assert "Torus(r1=1.0, r2=2.3701)" == repr(hs.Torus())


# ---------------------------------------------------------------------------
# borders and the fold
# ---------------------------------------------------------------------------


def border_curve(surf, k=4000):
    """Dense points on the border curve(s), from ``position`` only."""
    (u0, u1), (v0, v1) = surf.domain
    t = np.linspace(0, 1, k)
    if isinstance(surf, hs.Cylinder):
        uu = np.concatenate([u0 + (u1 - u0) * t] * 2)
        vv = np.concatenate([np.full(k, v0), np.full(k, v1)])
    else:
        su, sv = u0 + (u1 - u0) * t, v0 + (v1 - v0) * t
        uu = np.concatenate([su, su, np.full(k, u0), np.full(k, u1)])
        vv = np.concatenate([np.full(k, v0), np.full(k, v1), sv, sv])
    return surf.position(uu, vv)


@pytest.mark.parametrize("case", ["paraboloid", "wavy", "plane", "cylinder", "folded_60"])
def test_border_distance_is_a_lower_bound(case):
    surf = CASES[case]()
    smp = surf.sample(500, "random", seed=6)
    # Euclidean 3-D distance to the border is itself <= the distance along the surface
    euclid = cKDTree(border_curve(surf)).query(smp.clean_points)[0]
    assert np.all(smp.border_distance <= euclid + 1e-12)
    assert np.all(smp.border_distance >= 0)
    if case in ("plane", "cylinder", "folded_60"):
        # exact there: the nearest border point lies on the same straight ruling,
        # so surface and 3-D distance agree; the discretised border adds at most
        # half its spacing (<= 0.63e-3 for the cylinder, the coarsest)
        assert np.max(euclid - smp.border_distance) < 1e-3
    margin = 0.2
    assert np.array_equal(smp.interior(margin), smp.border_distance > margin)
    assert 0 < smp.interior(margin).sum() < len(smp)


def test_closed_surfaces_have_no_border():
    for surf in (hs.Sphere(), hs.Torus()):
        smp = surf.sample(100, "random", seed=0)
        assert np.all(np.isinf(smp.border_distance)) and np.all(smp.interior(10.0))
        assert np.all(np.isinf(smp.feature_distance)) and not np.any(smp.near_feature(1.0))


@pytest.mark.parametrize("angle", [30.0, 60.0, 90.0, 135.0, 180.0])
def test_folded_square_angle_and_fold_distance(angle):
    surf = hs.FoldedSquare(interior_angle=angle, size=1.0)
    # face normals from the clean geometry (three points on each face)
    left = surf.position([-0.9, -0.5, -0.9], [-0.5, 0.0, 0.5])
    right = surf.position([0.9, 0.5, 0.9], [-0.5, 0.0, 0.5])
    nl = np.cross(left[1] - left[0], left[2] - left[0])
    nr = np.cross(right[1] - right[0], right[2] - right[0])
    nl, nr = nl * np.sign(nl[2]), nr * np.sign(nr[2])  # both upward
    cos_n = nl @ nr / (np.linalg.norm(nl) * np.linalg.norm(nr))
    assert math.degrees(math.acos(np.clip(cos_n, -1, 1))) == pytest.approx(180 - angle, abs=1e-6)
    # interior angle between the faces, at the fold, measured inside the roof
    a = surf.position([0.7], [0.2])[0] - surf.position([0.0], [0.2])[0]
    b = surf.position([-0.4], [0.2])[0] - surf.position([0.0], [0.2])[0]
    cos_i = a @ b / (np.linalg.norm(a) * np.linalg.norm(b))
    assert math.degrees(math.acos(np.clip(cos_i, -1, 1))) == pytest.approx(angle, abs=1e-6)
    # analytic normals agree with the faces and point up; the fold is the ridge
    n = surf.normal([-0.5, 0.5, 0.0], [0.0, 0.0, 0.0])
    assert np.allclose(n[0], nl / np.linalg.norm(nl), atol=1e-14)
    assert np.allclose(n[1], nr / np.linalg.norm(nr), atol=1e-14)
    assert np.allclose(n[2], [0, 0, 1])  # bisector on the fold itself
    smp = surf.sample(2000, "random", seed=7)
    assert np.all(smp.clean_points[:, 2] <= 1e-15)  # fold at the top
    # distance to the fold line (the y axis), computed in 3-D ...
    p = smp.clean_points
    line = np.hypot(p[:, 0], p[:, 2])
    assert np.allclose(smp.feature_distance, line, rtol=1e-14, atol=1e-15)
    assert np.array_equal(smp.fold_distance, surf.fold_distance(smp.u, smp.v))
    # ... equals the distance along the surface (|u|, the flat square unfolded)
    assert np.allclose(smp.feature_distance, np.abs(smp.u), atol=1e-15)
    near = smp.near_feature(0.1)
    assert np.array_equal(near, line <= 0.1) and 0 < near.sum() < len(smp)
    assert np.all(smp.k1 == 0) and np.all(smp.mean == 0) and np.all(smp.umbilic)
    if angle == 180.0:
        assert np.allclose(smp.clean_points[:, 2], 0.0)


def test_sample_at_and_custom_graph():
    surf = wavy_graph()
    u = np.array([0.0, 0.5, -1.0])
    v = np.array([0.2, -0.3, 1.2])
    smp = surf.sample_at(u, v)
    assert smp.sampler == "custom" and len(smp) == 3
    assert np.array_equal(smp.clean_points, surf.position(u, v))
    assert np.allclose(smp.border_distance, [1.0, 0.7, 0.0])
    assert np.array_equal(smp.k1, surf.curvature(u, v).k1)
    noisy = surf.sample_at(u, v, noise=0.1, seed=0)
    assert noisy.sigma > 0 and not np.array_equal(noisy.points, noisy.clean_points)
    # scalars are length-1 arrays; callables may return scalars (broadcast)
    assert hs.Plane().position(0.5, 0.25).shape == (1, 3)
    bad = hs.Graph(*(lambda x, y: np.zeros(2) for _ in range(6)))
    with pytest.raises(HeatcurvError, match="shape"):
        bad.position(np.zeros(3), np.zeros(3))
    with pytest.raises(HeatcurvError):
        hs.Graph(1.0, *GRAPH_FUNCS["wavy"][1:])
