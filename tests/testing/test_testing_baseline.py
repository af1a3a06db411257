"""Tests of support.baseline: the k-NN quadric-fit baseline.

Its errors (k = 40, area-uniform random samples, 20000 points, seed 0) are
records (tests/records.json):

* unit-free sphere, R = 2.5: a systematic over-estimate of the mean curvature
  (the quadric misses the sphere's quartic term, ~(r/R)^2 with r ~ 0.22 the
  neighbourhood radius), every normal outward;
* torus r1 = 1, r2 = 2.3701 (larger, so r / r1 ~ 0.24): errors several times
  the sphere's.
"""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest

import support.baseline
from heatcurv import surfaces as hs
from heatcurv.errors import HeatcurvError
from heatcurv.surfaces.accuracy import compare, default_margin
from support.baseline import QuadricResult, quadric_curvature


@pytest.fixture(scope="module")
def sphere():
    smp = hs.Sphere(radius=2.5).sample(20000, "random", seed=0)
    return smp, quadric_curvature(smp.points)


@pytest.fixture(scope="module")
def torus():
    smp = hs.Torus().sample(20000, "random", seed=0)
    return smp, quadric_curvature(smp.points)


def rotation(seed):
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def errors(err: dict, d1=True) -> dict:
    """The recorded errors of a :func:`compare`: % (relative L1, total area), degrees (``_deg``)."""
    out = {name: 100 * err[f"rel_{name}"] for name in ("mean", "k1", "k2", "gaussian")}
    if d1:
        out["d1_deg"] = err["d1_deg"]
    return {**out, "normal_deg": err["normal_deg"], "area": 100 * err["area"]}


def test_sphere_mean_curvature_and_outward_normals(sphere, records):
    smp, res = sphere
    R = 2.5
    assert np.all(np.einsum("ij,ij->i", res.normals, smp.points) > 0.999 * R)  # outward
    assert np.median(res.mean) * R > 1.0  # the quadric over-estimates
    err = compare(smp, res)
    assert err["orientation"] == 1.0 and err["reliable"] == 1.0
    # no d1 on a sphere (umbilic); the k-NN area pi r^2 / (k - 1) is unbiased here
    records.check(
        "testing_baseline/sphere-random-20000-k40", **errors(err, d1=False),
        median_mean=100 * (np.median(res.mean) * R - 1), mean_max=100 * np.max(np.abs(res.mean * R - 1)),
    )


def test_torus_errors(torus, records):
    smp, res = torus
    err = compare(smp, res)
    assert err["orientation"] == 1.0 and err["reliable"] == 1.0
    records.check("testing_baseline/torus-random-20000-k40", **errors(err))


def test_shapes_and_invariants(torus):
    smp, res = torus
    n = len(smp)
    assert isinstance(res, QuadricResult) and len(res) == n
    for name in ("normals", "d1", "d2"):
        arr = getattr(res, name)
        assert arr.shape == (n, 3) and arr.dtype == np.float64
        assert np.allclose(np.linalg.norm(arr, axis=1), 1.0, atol=1e-12)
    for name in ("mean", "gaussian", "k1", "k2", "area", "spacing"):
        arr = getattr(res, name)
        assert arr.shape == (n,) and np.all(np.isfinite(arr))
    assert res.reliable.dtype == bool and res.reliable.shape == (n,)
    assert np.all(res.neighbours == 39) and res.options.k == 40 and res.options.method == "quadric"
    assert np.all(res.k1 >= res.k2)
    assert np.allclose(res.mean, 0.5 * (res.k1 + res.k2), rtol=1e-14, atol=1e-15)
    assert np.allclose(res.gaussian, res.k1 * res.k2, rtol=1e-14, atol=1e-15)
    assert np.max(np.abs(np.einsum("ij,ij->i", res.d1, res.normals))) < 1e-12
    assert np.max(np.abs(np.einsum("ij,ij->i", res.d2, res.normals))) < 1e-12
    assert np.max(np.abs(np.cross(res.d1, res.d2) - res.normals)) < 1e-12
    assert np.all(res.area > 0) and np.all(res.spacing > 0)
    assert set(res.as_dict()) == set(QuadricResult.FIELDS) | {"reliable"}
    assert "QuadricResult(n=20000" in repr(res)
    assert set(res.info["timings"]) == {"neighbours", "normals", "fit"}


def quadric_grid(m=101):
    """z = 0.3 x^2 - 0.2 x y + 0.1 y^2 on an m x m grid of [-1, 1]^2 (apex included)."""
    t = np.linspace(-1, 1, m)
    xx, yy = np.meshgrid(t, t)
    x, y = xx.ravel(), yy.ravel()
    pts = np.column_stack([x, y, 0.3 * x * x - 0.2 * x * y + 0.1 * y * y])
    return pts, int(np.flatnonzero((x == 0) & (y == 0))[0])


def test_exact_on_a_quadric_with_a_symmetric_neighbourhood(records):
    pts, apex = quadric_grid()
    # exact at the apex, upward normal: k = eigenvalues of -Hessian, Hessian [[0.6, -0.2], [-0.2, 0.2]]
    hess = np.array([[0.6, -0.2], [-0.2, 0.2]])
    evals, evecs = np.linalg.eigh(-hess)  # ascending: k2, k1
    k2_up, k1_up = evals
    d = np.sort(np.linalg.norm(pts - pts[apex], axis=1))
    for k in (37, 41, 45):
        # the k nearest are all points within d[k-1] (a gap follows), a
        # centrally symmetric set: (x, y, z) and (-x, -y, z) are equidistant.
        # Then the PCA normal is exactly vertical, the local frame sees the
        # exact quadric and the fit reproduces it: measured errors ~1e-15.
        assert d[k - 1] < d[k]
        res = quadric_curvature(pts, k=k)
        up = np.sign(res.normals[apex, 2])
        assert abs(abs(res.normals[apex, 2]) - 1) < 1e-14
        # for a downward normal (the rule orients this bowl "outward", down)
        # the signed values turn into k1 -> -k2, k2 -> -k1
        k1, k2 = (res.k1[apex], res.k2[apex]) if up > 0 else (-res.k2[apex], -res.k1[apex])
        assert k1 == pytest.approx(k1_up, abs=1e-10) and k2 == pytest.approx(k2_up, abs=1e-10)
        d1 = res.d1[apex] if up > 0 else res.d2[apex]
        assert abs(abs(d1[:2] @ evecs[:, 1]) - 1) < 1e-10
    # k = 40 cuts a pair of equidistant points: not symmetric, no longer exact to rounding
    res = quadric_curvature(pts, k=40)
    got, exact = np.sort(np.abs([res.k1[apex], res.k2[apex]])), np.sort(np.abs(evals))
    records.check("testing_baseline/quadric-grid-101x101-k40-apex", k_max=100 * np.max(np.abs(got / exact - 1)))


def test_the_gradient_of_the_fit_is_used(records):
    # normals tilted by 10 degrees: the fitted graph then has a gradient; with
    # the full fundamental forms the mean curvature stays as accurate as with
    # the exact normals, while the Hessian alone would be off by ~1 - cos(10 deg)^3 = 4.5 %
    R = 2.5
    smp = hs.Sphere(radius=R).sample(20000, "random", seed=0)
    n = smp.normals
    e1 = np.cross(n, [0.3, 0.5, 0.8])
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    tilted = math.cos(math.radians(10)) * n + math.sin(math.radians(10)) * e1
    res = quadric_curvature(smp.points, normals=3.0 * tilted)  # need not be unit
    error = 100 * np.mean(np.abs(res.mean * R - 1))
    records.check("testing_baseline/sphere-random-20000-k40-tilted-normals", mean=error)
    assert np.allclose(res.normals, tilted, atol=1e-12)  # the given normals are reported
    assert np.max(np.abs(np.cross(res.d1, res.d2) - res.normals)) < 1e-12


def test_given_normals_set_the_signs():
    smp = hs.Torus().sample(3000, "random", seed=1)
    a = quadric_curvature(smp.points, normals=smp.normals)
    b = quadric_curvature(smp.points, normals=-smp.normals)
    assert np.allclose(b.mean, -a.mean, rtol=1e-9, atol=1e-12)
    assert np.allclose(b.k1, -a.k2, rtol=1e-9, atol=1e-12)
    assert np.allclose(b.k2, -a.k1, rtol=1e-9, atol=1e-12)
    assert np.allclose(b.gaussian, a.gaussian, rtol=1e-9, atol=1e-12)


def test_any_size_and_position(torus):
    smp, res = torus
    for scale, atol in ((100.0, 1e-8), (0.1, 1e-5)):
        moved = smp.transformed(scale, rotation(1), [3e6, -5e6, 1e7])
        out = quadric_curvature(moved.points)
        # measured relative changes 6e-10 (x100) and 7e-7 (x0.1: coordinates
        # ~1e7 keep ~1e-9 of the 0.1-unit object, rounding of the input)
        assert np.max(np.abs(out.mean * scale - res.mean)) < atol * np.max(np.abs(res.mean))
        assert np.max(np.abs(out.normals - moved.normals)) < 0.05  # same (outward) orientation
        assert np.allclose(out.area, res.area * scale**2, rtol=1e-4)


def test_scan_sample_runs(torus, records):
    smp = hs.Torus().scan(5000, seed=0)
    res = quadric_curvature(smp.points)
    err = compare(smp, res)  # default margin: res.support_radius = max(spacing)
    assert err["orientation"] == 1.0
    records.check("testing_baseline/torus-scan-5000-k40", mean=100 * err["rel_mean"])


def test_support_radius_is_the_default_margin(torus):
    # the quadric result states its neighbourhood radius; no fake options.alpha
    smp, res = torus
    assert res.support_radius == float(np.max(res.spacing))
    assert not hasattr(res.options, "alpha")
    assert default_margin(res) == res.support_radius
    a, b = compare(smp, res), compare(smp, res, margin=float(np.max(res.spacing)))
    assert np.array_equal(a["interior"], b["interior"]) and a["rel_mean"] == b["rel_mean"]


def test_errors():
    pts = hs.Sphere().sample(200, "fibonacci").points
    with pytest.raises(HeatcurvError, match="shape"):
        quadric_curvature(pts[:, :2])
    bad = pts.copy()
    bad[3, 1] = np.nan
    with pytest.raises(HeatcurvError, match="NaN or infinite"):
        quadric_curvature(bad)
    with pytest.raises(HeatcurvError, match="at least 7"):
        quadric_curvature(pts, k=6)
    with pytest.raises(HeatcurvError, match="integer"):
        quadric_curvature(pts, k=40.5)
    with pytest.raises(HeatcurvError, match="too few points: 30 distinct"):
        quadric_curvature(pts[:30])
    with pytest.raises(HeatcurvError, match="normals"):
        quadric_curvature(pts, normals=pts[:10])
    with pytest.raises(HeatcurvError, match="zero length"):
        quadric_curvature(pts, normals=np.zeros_like(pts))


def test_collinear_input_is_refused():
    # points on a line: no surface; the shared input checks say so
    t = np.linspace(0, 1, 100)
    line = np.column_stack([t, 2 * t, -t])
    with pytest.raises(HeatcurvError, match="lie on one line"):
        quadric_curvature(line, k=10)


def test_duplicates_share_values_and_area():
    pts = hs.Sphere(radius=2.0).sample(2000, "random", seed=1).points
    twice = np.vstack([pts, pts[:50]])
    res, ref = quadric_curvature(twice), quadric_curvature(pts)
    np.testing.assert_allclose(res.mean[2000:], res.mean[:50])
    np.testing.assert_allclose(res.mean[:2000], ref.mean, rtol=1e-12)
    assert res.area.sum() == pytest.approx(ref.area.sum(), rel=1e-12)


def test_docstring_example():
    result = doctest.testmod(support.baseline, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
