"""The shared heat-kernel operator object and the laplacian() front end."""

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.operators.laplace_beltrami import laplace_beltrami_matrix
from heatcurv.operators.mean_curvature import mean_curvature_normal
from heatcurv.operators.operator import HeatKernelOperator, build_operator


@pytest.fixture(scope="module")
def sphere_op():
    return HeatKernelOperator.from_points(surfaces.Sphere().sample(3000, "fibonacci").points, method="paper")


def test_matrix_and_apply_are_eq_2_9(sphere_op, records):
    op = sphere_op
    L = op.matrix()
    expect = laplace_beltrami_matrix(op.neighbourhood, op.weights, op.areas, op.h, op.m)
    assert abs(L - expect).max() == 0
    np.testing.assert_allclose(op.apply(np.ones(len(op.points))), 0.0, atol=1e-9)
    # coordinate functions of the unit sphere: L z = 2 z / R^2 (the paper's positive operator)
    z = op.points[:, 2]
    eigenvalue = np.median(op.apply(z)[np.abs(z) > 0.5] / z[np.abs(z) > 0.5])
    records.check("operator/sphere-fibonacci-3000-paper-apply", median=100 * (eigenvalue / 2.0 - 1))
    with pytest.raises(HeatcurvError, match="the field has 5 rows, the operator 3000 points"):
        op.apply(np.ones(5))


def test_mean_curvature_normal_is_L_applied_to_the_coordinates(sphere_op, records):
    op = sphere_op
    K = op.mean_curvature_normal()
    np.testing.assert_allclose(K, op.matrix() @ op.points, rtol=1e-9, atol=1e-9)
    pairwise = mean_curvature_normal(op.points, op.neighbourhood, None, op.areas, op.h, op.m)  # weights not stored
    np.testing.assert_allclose(K, pairwise, rtol=1e-9, atol=1e-12)
    # 2 kappa_M n = 2 n on the unit sphere
    median = np.median(np.linalg.norm(K, axis=1))
    records.check("operator/sphere-fibonacci-3000-paper-mean-curvature-normal", median=100 * (median / 2.0 - 1))


def test_build_operator_times_its_stages_and_keeps_weights_lazy():
    pts = surfaces.Torus().sample(4000, "random", seed=1).points
    op = build_operator(pts)  # default: density spacing and areas, no stored weights
    assert list(op.timings) == ["validate", "neighbours", "spacing", "areas"]
    assert op.stored_weights is None and op.weights.shape == (op.neighbourhood.n_pairs,)
    assert op.stored_weights is op.weights


def test_laplacian_front_end_in_input_order():
    pts = surfaces.Sphere().sample(1500, "fibonacci").points
    perm = np.random.default_rng(0).permutation(len(pts))
    L, area = heatcurv.laplacian(pts)
    Lp, area_p = heatcurv.laplacian(pts[perm])
    np.testing.assert_allclose(area_p, area[perm], rtol=1e-12)
    np.testing.assert_allclose(Lp.toarray(), L.toarray()[np.ix_(perm, perm)], atol=1e-9)
    with pytest.raises(HeatcurvError, match="exact duplicate"):
        heatcurv.laplacian(np.vstack([pts, pts[:1]]))


def test_laplacian_annihilates_constants_and_is_symmetric_with_areas(sphere_sample):
    pts = sphere_sample.points[:2000]
    L, area = heatcurv.laplacian(pts)
    assert L.shape == (2000, 2000)
    np.testing.assert_allclose(L @ np.ones(2000), 0.0, atol=1e-9 * abs(L).max())
    S = (L.multiply(area[:, None])).toarray()
    np.testing.assert_allclose(S, S.T, atol=1e-12 * np.abs(S).max())
    assert np.all(L.diagonal() > 0) and L.nnz > 0


def test_laplacian_rows_follow_the_input_order(sphere_sample):
    pts = sphere_sample.points[:1500]
    perm = np.random.default_rng(0).permutation(1500)
    L, area = heatcurv.laplacian(pts)
    Lp, areap = heatcurv.laplacian(pts[perm])
    np.testing.assert_allclose(areap, area[perm], rtol=1e-9)
    f = pts[:, 0] ** 2
    np.testing.assert_allclose(Lp @ f[perm], (L @ f)[perm], rtol=1e-8, atol=1e-8)


def test_laplacian_eigenfunctions_of_the_sphere(records):
    # spherical harmonics of degree l: Delta Y = l (l + 1) / R^2 Y (positive operator, eq 2.1)
    R = 2.0
    pts = surfaces.Sphere(radius=R).sample(8000, "fibonacci").points
    L, _ = heatcurv.laplacian(pts, method="paper")  # the paper's operator (eq 2.9); the default's own tests pin it
    x, y, z = pts.T
    # relative residuals at n = 8000
    residuals = {
        name: 100 * np.linalg.norm(L @ f - lam * f) / np.linalg.norm(lam * f)
        for name, f, lam in [("l1", z, 2 / R**2), ("l2", x * y, 6 / R**2)]
    }
    records.check("operator/sphere-fibonacci-8000-paper-eigenfunctions", **residuals)


def test_laplacian_of_polynomials_on_a_plane(plane_grid, records):
    # Delta(x^2 + y^2) = -4 and Delta(linear) = 0 in the positive convention, in the deep interior
    # (12 h from the border); worst errors in % of 4
    L, _ = heatcurv.laplacian(plane_grid.points, method="paper")
    x, y, _ = plane_grid.points.T
    deep = plane_grid.interior(12 * 2 / 60 + 1e-9)
    records.check(
        "operator/plane-grid-3721-paper-polynomials",
        quadratic=100 * np.abs(L @ (x * x + y * y) + 4.0)[deep].max() / 4,
        linear=100 * np.abs(L @ (2 * x - 3 * y + 1))[deep].max() / 4,
    )


def test_laplacian_rejects_duplicates(sphere_sample):
    pts = np.vstack([sphere_sample.points[:500], sphere_sample.points[:3]])
    with pytest.raises(HeatcurvError, match="3 exact duplicate"):
        heatcurv.laplacian(pts)
