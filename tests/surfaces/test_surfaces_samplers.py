"""Tests of heatcurv.surfaces.samplers: counts, layouts, area-uniformity and reproducibility of the samplers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree
from surfaces_helpers import CASES, binomial_check, residual

from heatcurv import surfaces as hs


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("sampler", hs.SAMPLERS)
def test_sampler_counts_and_points_on_surface(case, sampler):
    surf = CASES[case]()
    n = 1000
    smp = surf.sample(n, sampler=sampler, seed=11)
    m = len(smp)
    if sampler in ("fibonacci", "random", "scan") or isinstance(surf, (hs.Sphere, hs.Ellipsoid)):
        assert m == n  # "scan": the excess over ~1.03 n is dropped
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
    if sampler == "scan":
        assert smp.viewpoints.shape == (3, 3) and smp.viewpoint_index.shape == (m,)
    else:
        assert smp.viewpoints is None and smp.viewpoint_index is None
    assert np.array_equal(smp.clean_points, surf.position(smp.u, smp.v))
    assert np.array_equal(smp.normals, surf.normal(smp.u, smp.v))
    assert smp.total_area == surf.area()
    (u0, u1), (v0, v1) = surf.domain
    assert np.all((smp.u >= u0) & (smp.u <= u1) & (smp.v >= v0) & (smp.v <= v1))
    if surf.periodic[0]:
        assert np.all(smp.u < u1)
    if surf.periodic[1]:
        assert np.all(smp.v < v1)
    # no two points coincide (seams are not duplicated); random points and
    # overlapping scans may legitimately come close, so only the
    # lattice-based samplers are checked
    if sampler not in ("random", "scan"):
        d, _ = cKDTree(smp.clean_points).query(smp.clean_points, 2)
        assert d[:, 1].min() > 1e-3


def test_random_is_area_uniform_sphere():
    n = 20000
    z = hs.Sphere().sample(n, "random", seed=1).clean_points[:, 2]
    binomial_check(np.mean(z > 0.5), 0.25, n)  # Archimedes: cap area fraction (1-0.5)/2
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
    binomial_check(np.mean(outer), 0.5 + r1 / (math.pi * r2), n)


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
    binomial_check(np.mean(inside), p, n)


def test_fibonacci_sphere_is_nearly_uniform(records):
    for n in (500, 5000):
        p = hs.Sphere().sample(n, "fibonacci").points
        d, _ = cKDTree(p).query(p, 2)
        d = d[:, 1]
        # spacing ~ sqrt(4 pi / n), within a narrow spread: the max/min nearest-neighbour ratio's excess over 1
        # and the smallest distance's shortfall, in %
        assert d.max() * math.sqrt(n) < math.sqrt(4 * math.pi)
        records.check(
            f"surfaces_samplers/sphere-fibonacci-{n}", spread=100 * (d.max() / d.min() - 1),
            min_spacing=100 * (1 - d.min() * math.sqrt(n) / math.sqrt(4 * math.pi)),
        )
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
    binomial_check(np.mean(jit.points[:, 2] > 0), 0.5, n)


@pytest.mark.parametrize("sampler", hs.SAMPLERS)
def test_seed_reproducibility(sampler):
    surf = hs.Torus()
    a = surf.sample(500, sampler, noise=0.02, seed=123)
    b = surf.sample(500, sampler, noise=0.02, seed=123)
    c = surf.sample(500, sampler, noise=0.02, seed=124)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.u, b.u)
    assert not np.array_equal(a.points, c.points)
    if sampler in ("random", "jittered", "scan"):  # scan: the dropped excess is random
        assert not np.array_equal(a.clean_points, c.clean_points)
    else:  # deterministic layouts
        assert np.array_equal(a.clean_points, c.clean_points)
