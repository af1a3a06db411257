"""Tests of heatcurv.surfaces.closed: sphere, ellipsoid and torus against textbook formulas (and the
closed-form areas of every family).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from surfaces_helpers import binomial_check

from heatcurv import surfaces as hs


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


def test_sphere_centre():
    import warnings

    from heatcurv import HeatcurvError

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the British name warns about nothing
        surf = hs.Sphere(1.5, (1.0, 2.0, 3.0))
        assert np.array_equal(surf.centre, [1.0, 2.0, 3.0])
        assert np.array_equal(hs.Sphere(centre=(1, 2, 3)).centre, surf.centre)
        assert np.array_equal(hs.Sphere().centre, [0.0, 0.0, 0.0])
        assert repr(surf) == "Sphere(radius=1.5, centre=(1.0, 2.0, 3.0))"
        assert np.allclose(surf.implicit(surf.sample(50, "random", seed=0).points), 0.0, atol=1e-14)
    with pytest.raises(HeatcurvError, match=r"centre must be 3 finite numbers"):
        hs.Sphere(centre=(0, 0))


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


def ellipsoid_area_elliptic(a, b, c):
    """Legendre's closed form with incomplete elliptic integrals (a >= b >= c)."""
    from scipy.special import ellipeinc, ellipkinc

    a, b, c = sorted((a, b, c), reverse=True)
    phi = math.acos(c / a)
    m = a * a * (b * b - c * c) / (b * b * (a * a - c * c))
    e, f = ellipeinc(phi, m), ellipkinc(phi, m)
    return 2 * math.pi * c * c + 2 * math.pi * a * b / math.sin(phi) * (
        e * math.sin(phi) ** 2 + f * math.cos(phi) ** 2
    )


@pytest.mark.parametrize("abc", [(1.0, 0.8, 0.6), (0.7, 1.3, 1.9), (3.0, 1.0, 0.2)])
def test_ellipsoid_area_against_elliptic_integrals(abc):
    # measured agreement 2e-15, 3e-15 and 8e-13 (the flat 3 : 1 : 0.2 one)
    assert hs.Ellipsoid(*abc).area() == pytest.approx(ellipsoid_area_elliptic(*abc), rel=1e-11)


def test_ellipsoid_textbook_formulas_and_special_points():
    a, b, c = 1.0, 0.8, 0.6
    surf = hs.Ellipsoid(a, b, c)
    rng = np.random.default_rng(0)
    u = rng.uniform(0, 2 * math.pi, 300)
    v = np.concatenate([rng.uniform(-math.pi / 2, math.pi / 2, 296), [math.pi / 2, -math.pi / 2] * 2])
    p = surf.position(u, v)
    x, y, z = p.T
    s2 = x**2 / a**4 + y**2 / b**4 + z**2 / c**4
    gauss = 1 / (a * b * c) ** 2 / s2**2
    mean = (a * a + b * b + c * c - np.sum(p * p, axis=1)) / (2 * (a * b * c) ** 2 * s2**1.5)
    cv = surf.curvature(u, v)  # includes the poles, where X_u = 0
    assert np.allclose(cv.gaussian, gauss, rtol=1e-12)
    assert np.allclose(cv.mean, mean, rtol=1e-12)
    n = surf.normal(u, v)
    assert np.allclose(n, np.column_stack([x / a**2, y / b**2, z / c**2]) / np.sqrt(s2)[:, None])
    assert np.allclose(np.cross(cv.d1, cv.d2), n, atol=1e-14)
    # poles (0, 0, +-c): k = c / a^2 along x, c / b^2 along y
    pole = surf.curvature([0.3], [math.pi / 2])
    assert (pole.k1[0], pole.k2[0]) == pytest.approx((c / b**2, c / a**2), rel=1e-14)
    assert np.allclose(np.abs(pole.d1[0]), [0, 1, 0], atol=1e-14)
    # (a, 0, 0): k = a / c^2 along z (the larger), a / b^2 along y
    tip = surf.curvature([0.0], [0.0])
    assert (tip.k1[0], tip.k2[0]) == pytest.approx((a / c**2, a / b**2), rel=1e-14)
    assert np.allclose(np.abs(tip.d1[0]), [0, 0, 1], atol=1e-14)


def test_ellipsoid_umbilics():
    a, b, c = 1.0, 0.8, 0.6
    surf = hs.Ellipsoid(a, b, c)
    x = a * math.sqrt((a * a - b * b) / (a * a - c * c))
    z = c * math.sqrt((b * b - c * c) / (a * a - c * c))
    pts = np.array([[x, 0, z], [-x, 0, z], [x, 0, -z], [-x, 0, -z]])
    u, v = surf.parameters_of(pts)
    cv = surf.curvature(u, v)
    assert np.all(cv.umbilic) and np.allclose(cv.k1, cv.k2, rtol=1e-14)
    # there |g|^2 = x^2/a^4 + z^2/c^4 = b^2 / (a^2 c^2), so k = sqrt(K) = 1 / (a b c |g|^2) = a c / b^3
    assert np.allclose(cv.k1, a * c / b**3, rtol=1e-13)
    smp = surf.sample(20000, "random", seed=0)
    assert not np.any(smp.umbilic)
    assert np.min(smp.k1 - smp.k2) > 0


def test_ellipsoid_random_is_area_uniform():
    a, b, c, n = 1.0, 0.8, 0.6, 20000
    surf = hs.Ellipsoid(a, b, c)
    z = surf.sample(n, "random", seed=4).clean_points[:, 2]
    h = 1e-6

    def element(v, u):  # |X_u x X_v| by central differences of position only
        P = surf.position([u + h, u - h, u, u], [v, v, v + h, v - h])
        return float(np.linalg.norm(np.cross((P[0] - P[1]) / (2 * h), (P[2] - P[3]) / (2 * h))))

    cap, _ = integrate.dblquad(element, 0, 2 * math.pi, math.asin(0.5), math.pi / 2, epsrel=1e-7)
    p = cap / surf.area()  # ~0.223 (0.25 on a sphere)
    assert abs(p - 0.25) > 0.02
    binomial_check(np.mean(z > 0.5 * c), p, n)


def test_ellipsoid_fibonacci_grid_and_jittered_are_the_stretched_sphere_lattice():
    n = 2000
    surf = hs.Ellipsoid(1.0, 0.8, 0.6)
    axes = np.array([1.0, 0.8, 0.6])
    for sampler, seed in (("fibonacci", None), ("grid", None), ("jittered", 3)):
        ell = surf.sample(n, sampler, seed=seed).clean_points
        sph = hs.Sphere().sample(n, sampler, seed=seed).clean_points
        assert np.allclose(ell, sph * axes, atol=1e-15)
    # stratified in z / c like the sphere, hence not area-uniform (area fraction ~0.223)
    z = surf.sample(n, "fibonacci").clean_points[:, 2]
    assert abs(np.mean(z > 0.3) - 0.25) <= 1.0 / n
