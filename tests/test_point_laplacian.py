"""The default point-cloud Laplacian (heatcurv.operators.point_laplacian): invariants, spectra against exact values."""

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, PointCloudLaplacian, surfaces
from support.mesh_laplacian import cotangent_laplacian, mesh_eigenvalues, torus_mesh

# spherical-harmonic eigenvalues l (l + 1) of the unit sphere, l = 1..3, with multiplicity 2l + 1
SPHERE = np.concatenate([[d * (d + 1)] * (2 * d + 1) for d in range(1, 4)])


@pytest.fixture(scope="module")
def random_sphere():
    pts = surfaces.Sphere().sample(4000, "random", seed=0).points
    return pts, PointCloudLaplacian(pts)


def test_stiffness_is_symmetric_psd_rows_sum_to_zero_areas_sum_to_the_area(random_sphere, records):
    pts, lap = random_sphere
    L, area = heatcurv.laplacian(pts)
    S = L.multiply(area[:, None]).tocsr()
    assert abs(S - S.T).max() < 1e-12 * abs(S).max()
    np.testing.assert_allclose(L @ np.ones(len(pts)), 0.0, atol=1e-10 * abs(L).max())
    # PSD: the smallest eigenvalue of S v = lam A v is 0 (the constants), the next 2 (l = 1)
    values, _ = lap.eigenpairs(2)
    assert abs(values[0]) < 1e-8 and values[1] > 1.9
    # areas (tangent-plane Voronoi cells): positive, and their sum the sphere's
    assert np.all(area > 0)
    records.check("point_laplacian/sphere-random-4000-areas", area=100 * (area.sum() / (4 * np.pi) - 1))
    np.testing.assert_allclose(area, lap.area, rtol=1e-12)


def test_random_sphere_spectrum(random_sphere, records):
    # 4000 random points: mean relative error of the eigenvalues of each degree l = 1..3, and the worst one
    _, lap = random_sphere
    values, vectors = lap.eigenpairs(16)
    err = np.abs(values[1:] - SPHERE) / SPHERE
    degrees = {f"l{d}": 100 * err[d * d - 1 : (d + 1) ** 2 - 1].mean() for d in range(1, 4)}
    # eigenvectors are mass-orthonormal, and the degree-1 ones span the coordinates
    gram = vectors.T @ (lap.area[:, None] * vectors)
    np.testing.assert_allclose(gram, np.eye(16), atol=1e-8)
    pts = lap.points
    coeff = vectors[:, 1:4].T @ (lap.area[:, None] * pts)
    residual = pts - vectors[:, 1:4] @ coeff
    records.check(
        "point_laplacian/sphere-random-4000-spectrum", **degrees, worst=100 * err.max(),
        coordinates=100 * np.linalg.norm(residual) / np.linalg.norm(pts),  # the part outside their span
    )


def test_fibonacci_sphere_spectrum_is_within_two_thirds_of_a_percent(records):
    # a regular sampling, 3000 points
    pts = surfaces.Sphere(radius=2.0).sample(3000, "fibonacci").points
    values, _ = PointCloudLaplacian(pts).eigenpairs(16)
    err = np.abs(values[1:] * 4.0 - SPHERE) / SPHERE
    assert err.max() < 2 / 3 * 0.01
    records.check("point_laplacian/sphere-fibonacci-3000-spectrum", mean=100 * err.mean(), worst=100 * err.max())


def test_random_torus_against_a_cotangent_mesh(records):
    # reference: cotangent Laplacian of a 64 x 149 periodic grid mesh (first ten eigenvalues within
    # 2e-4 of the 256 x 597 mesh); the area sum is that of cells mapped at the chord's length
    ref = mesh_eigenvalues(*cotangent_laplacian(*torus_mesh(0.6, 1.4, 64, 149)), 11)[1:]
    torus = surfaces.Torus(0.6, 1.4)
    pts = torus.sample(5000, "random", seed=0).points
    lap = PointCloudLaplacian(pts)
    values, _ = lap.eigenpairs(11)
    err = np.abs(values[1:] - ref) / ref
    records.check(
        "point_laplacian/torus-random-5000-mesh", mean=100 * err.mean(), worst=100 * err.max(),
        area=100 * (lap.area.sum() / torus.area() - 1),
    )


# 4000 points of each sampler; the jittered one puts a row of points on the border, whose cells end 0.2
# spacings beyond them (its total area is the largest)
@pytest.mark.parametrize("sampler", ["random", "jittered", "scan"])
def test_square_neumann_spectrum_and_area(sampler, records):
    # [-1, 1]^2 with a free border: the first 9 nonzero eigenvalues pi^2 (i^2 + j^2) / 4
    pts = np.unique(surfaces.Plane(1.0).sample(4000, sampler, seed=0).points, axis=0)
    exact = np.sort([np.pi**2 * (i * i + j * j) / 4 for i in range(5) for j in range(5)])[1:10]
    lap = PointCloudLaplacian(pts)
    values, _ = lap.eigenpairs(10)
    err = np.abs(values[1:] - exact) / exact
    records.check(
        f"point_laplacian/square-{sampler}-4000-neumann", mean=100 * err.mean(), worst=100 * err.max(),
        area=100 * (lap.area.sum() / 4.0 - 1),
    )


def test_voronoi_cells_of_a_grid_are_exact():
    # interior cells of a square grid of spacing a are a x a squares; a border cell (not a corner) is open and
    # ends BORDER_GAP spacings beyond its point: a (a/2 + 0.2 a); a corner (a/2 + 0.2 a)^2 only where the two
    # clips agree, so corners are left out
    from scipy.spatial import cKDTree

    from heatcurv.operators.point_laplacian import BORDER_GAP, VORONOI_NEIGHBOURS, _voronoi_areas

    a = 0.1
    g = np.arange(30) * a
    X = np.column_stack([np.repeat(g, 30), np.tile(g, 30), np.zeros(900)])
    X = X @ np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0].T  # any plane
    area, normals, opened = _voronoi_areas(X, cKDTree(X), VORONOI_NEIGHBOURS, BORDER_GAP, 1)
    i, j = np.divmod(np.arange(900), 30)
    edge = np.minimum(np.minimum(i, 29 - i), np.minimum(j, 29 - j))
    corner = (np.minimum(i, 29 - i) == 0) & (np.minimum(j, 29 - j) == 0)
    np.testing.assert_allclose(area[edge >= 1], a * a, rtol=1e-9)
    assert not opened[edge >= 1].any() and opened[(edge == 0) & ~corner].all()
    np.testing.assert_allclose(area[(edge == 0) & ~corner], a * a * (0.5 + BORDER_GAP), rtol=1e-9)


def test_rows_are_calibrated_exactly_isotropic_inside_along_the_border_at_it(records):
    # L1 (x - x_i)^2 evaluated at x_i is -(1/A_i) sum_j W_ij |d_ij|^2 = -4 in the interior (isotropic
    # calibration, the Laplacian of |x|^2 in the plane), to rounding; at a point on a straight border the
    # calibration is along the border: L1 (y - y_i)^2 = -2 there (the Laplacian of y^2), not to rounding
    # (the direction calibrated is normal to the row's first moment, which the scalings c_j of the
    # partners tilt where they are not mirror-symmetric along the border)
    a = 0.05
    g = np.arange(40) * a
    X = np.column_stack([np.repeat(g, 40), np.tile(g, 40), np.zeros(1600)])
    lap = PointCloudLaplacian(X, order=1)
    S = lap.first_order.tocoo()
    off = S.row != S.col
    r, c, w = S.row[off], S.col[off], -S.data[off]
    d = X[c] - X[r]
    iso = np.bincount(r, w * np.einsum("ij,ij->i", d, d), 1600) / lap.area
    along_y = np.bincount(r, w * d[:, 1] ** 2, 1600) / lap.area
    i, j = np.divmod(np.arange(1600), 40)
    inside = (np.minimum(i, 39 - i) >= 8) & (np.minimum(j, 39 - j) >= 8)  # beyond the border band
    np.testing.assert_allclose(-iso[inside], -4.0, rtol=1e-7)
    border = (i == 0) & (j >= 8) & (j <= 31)  # the x = 0 edge, away from the corners
    # the normal moment there is smaller than the along-border one (partners along the border carry larger
    # scalings): iso < 4, by as much as an isotropic calibration (iso = 4) would have overweighted the
    # along-border energy of these rows
    assert np.all(iso[border] < 4.0)
    records.check(
        "point_laplacian/grid-40x40-border-calibration", along=100 * np.abs(along_y[border] / 2.0 - 1).max(),
        iso_least=100 * (1 - iso[border].max() / 4), iso_most=100 * (1 - iso[border].min() / 4),
    )


def test_order_rotation_and_scale():
    pts = surfaces.Ellipsoid().sample(2500, "random", seed=3).points
    lap = PointCloudLaplacian(pts)
    values, _ = lap.eigenpairs(8)
    perm = np.random.default_rng(1).permutation(len(pts))
    L, area = heatcurv.laplacian(pts)
    Lp, area_p = heatcurv.laplacian(pts[perm])
    np.testing.assert_allclose(area_p, area[perm], rtol=1e-9)
    f = pts[:, 0] ** 2 - pts[:, 2]
    np.testing.assert_allclose(Lp @ f[perm], (L @ f)[perm], rtol=1e-8, atol=1e-8 * np.abs(L @ f).max())
    q, _ = np.linalg.qr(np.random.default_rng(2).normal(size=(3, 3)))
    s = 7.5
    moved = PointCloudLaplacian(s * pts @ q.T + np.array([1e3, -2e3, 5.0]))
    moved_values, _ = moved.eigenpairs(8)
    np.testing.assert_allclose(moved_values[1:] * s**2, values[1:], rtol=1e-6)
    np.testing.assert_allclose(moved.area / s**2, lap.area, rtol=1e-6)


def test_mean_curvature_normal_sign_convention(random_sphere, records):
    # L is the positive operator: L x = 2 kappa_M n, +2 outward on the unit sphere (eq 2.10). Errors: of the
    # normal part n.Lx against 2 (worst, median), and the relative residual |Lx - 2n| / |2n|, whose
    # tangential part is sampling noise on random points
    def errors(K, pts, median=False):
        normal_part = np.einsum("ij,ij->i", K, pts)
        assert np.all(normal_part > 0)  # outward: the sign convention
        out = {"normal_worst": 100 * np.abs(normal_part / 2.0 - 1).max()}
        if median:
            out["normal_median"] = 100 * abs(np.median(normal_part) / 2.0 - 1)
        return {**out, "residual": 100 * np.linalg.norm(K - 2 * pts) / np.linalg.norm(2 * pts)}

    pts = surfaces.Sphere().sample(4000, "fibonacci").points
    K = PointCloudLaplacian(pts).mean_curvature_normal()
    records.check("point_laplacian/sphere-fibonacci-4000-mean-curvature-normal", **errors(K, pts))
    random_pts, lap = random_sphere
    K = lap.mean_curvature_normal()
    records.check("point_laplacian/sphere-random-4000-mean-curvature-normal", **errors(K, random_pts, median=True))
    K1 = PointCloudLaplacian(random_pts, order=1).mean_curvature_normal()
    records.check("point_laplacian/sphere-random-4000-order1-mean-curvature-normal", **errors(K1, random_pts))


def test_heat_diffusion_of_a_harmonic_and_conservation(random_sphere, records):
    # u = z is an eigenfunction (lam = 2): backward Euler with 20 steps gives (1 + 2 tau)^-20 z
    pts, lap = random_sphere
    z = pts[:, 2]
    u = lap.heat(z, 0.2, steps=20)
    expected = (1 + 2 * 0.01) ** -20
    decay = np.sum(lap.area * u * z) / np.sum(lap.area * z * z)
    records.check("point_laplacian/sphere-random-4000-heat-harmonic", decay=100 * (decay / expected - 1))
    spike = np.zeros(len(pts))
    spike[0] = 1.0 / lap.area[0]
    spread = lap.heat(spike, 0.05, steps=5)
    assert np.sum(lap.area * spread) == pytest.approx(1.0, rel=1e-9)
    assert spread.min() > -1e-9 and spread.max() < spike.max()


def sphere_heat_series(cos_angle, decay, degrees=120):
    """``sum_l (2l + 1) / (4 pi) decay(l (l + 1)) P_l(cos_angle)``: heat from a unit point source on the unit sphere."""
    from numpy.polynomial import legendre

    degree = np.arange(degrees + 1)
    return legendre.legval(cos_angle, (2 * degree + 1) / (4 * np.pi) * decay(degree * (degree + 1.0)))


def test_heat_from_a_point_against_the_exact_heat_kernel_of_the_sphere(random_sphere, records):
    # a unit of heat at one point, t = 0.1 in 100 steps; the exact kernel sum_l (2l+1)/(4 pi) e^(-l(l+1) t) P_l,
    # and the same series with backward Euler's decay (1 + tau l(l+1))^-steps: the operator's error alone
    pts, lap = random_sphere
    spike = np.zeros(len(pts))
    spike[0] = 1.0 / lap.area[0]
    time, steps = 0.1, 100
    u = lap.heat(spike, time, steps)
    cos_angle = np.clip(pts @ pts[0], -1.0, 1.0)
    euler = sphere_heat_series(cos_angle, lambda lam: (1.0 + time / steps * lam) ** -steps)
    exact = sphere_heat_series(cos_angle, lambda lam: np.exp(-lam * time))

    def relative(a, b):  # area-weighted L2, %
        return 100 * np.sqrt(np.sum(lap.area * (a - b) ** 2) / np.sum(lap.area * b**2))

    records.check("point_laplacian/sphere-random-4000-heat-kernel-t0.1", euler=relative(u, euler),
                  exact=relative(u, exact))
    assert np.sum(lap.area * u) == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize(
    "points, options, message",
    [
        (np.full((100, 3), np.nan), {}, "finite|NaN|nan"),
        (np.zeros((5, 3)), {}, "points"),
        (np.ones((100, 2)), {}, "shape|3"),
        (None, {"neighbours": 3}, "neighbours"),
        (None, {"width": 2.0}, "width"),
        (None, {"order": 3}, "order"),
        (None, {"workers": 0}, "workers = 0 is outside its range"),
        (None, {"alpha": 4}, "unknown option"),
        ("outliers", {}, "did not converge.*isolated outliers"),
    ],
)
def test_bad_input_is_a_heatcurv_error(points, options, message):
    if isinstance(points, str):  # points far off the surface, kernel weights ~1e-19: a NaN residual, not NaN out
        points = surfaces.Sphere().sample(30000, "random", seed=0).points
        points[:50] *= 1.3
    elif points is None:
        points = surfaces.Sphere().sample(500, "random", seed=0).points
    with pytest.raises(HeatcurvError, match=message):
        heatcurv.laplacian(points, **options)


def test_duplicates_and_bad_queries_are_heatcurv_errors(random_sphere):
    pts, lap = random_sphere
    with pytest.raises(HeatcurvError, match="2 exact duplicate"):
        heatcurv.laplacian(np.vstack([pts[:600], pts[:2]]))
    with pytest.raises(HeatcurvError, match="method"):
        heatcurv.laplacian(pts, method="robust")
    with pytest.raises(HeatcurvError, match="k must"):
        lap.eigenpairs(0)
    with pytest.raises(HeatcurvError, match="time"):
        lap.heat(pts[:, 0], -1.0)
    with pytest.raises(HeatcurvError, match="shape"):
        lap.heat(pts[:10, 0], 1.0)
    with pytest.raises(HeatcurvError, match="values hold 1 NaN or infinite entries"):
        lap.heat(np.r_[np.nan, pts[1:, 0]], 1.0)


@pytest.mark.parametrize("cholesky", [True, False])
def test_spd_factor_solves_the_shifted_stiffness_as_a_pivoting_factorisation_does(random_sphere, cholesky, monkeypatch):
    # CHOLMOD's Cholesky, or SuperLU without row pivoting (no cvxopt, complex matrices): a positive definite
    # matrix needs no pivoting, so both give the solution of SuperLU's default, to rounding
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from heatcurv.operators import point_laplacian

    if cholesky:
        pytest.importorskip("cvxopt", reason="cvxopt has no wheel for this platform")
    else:
        monkeypatch.setattr(point_laplacian, "cholmod", None)
    pts, lap = random_sphere
    shifted = lap.first_order + 0.05 * sp.diags(lap.area)
    rhs = np.column_stack([pts[:, 2], np.random.default_rng(0).normal(size=len(pts))])
    factor = point_laplacian.spd_factor(shifted)
    assert isinstance(factor, point_laplacian.CholeskyFactor) == cholesky
    got = factor.solve(rhs)
    want = spla.splu(shifted.tocsc()).solve(rhs)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())
    np.testing.assert_allclose(shifted @ got, rhs, atol=1e-9 * np.abs(rhs).max())
    np.testing.assert_allclose(factor.solve(rhs[:, 1]), want[:, 1], rtol=1e-9, atol=1e-12 * np.abs(want).max())
    complex_factor = point_laplacian.spd_factor(shifted.astype(complex))
    assert not isinstance(complex_factor, point_laplacian.CholeskyFactor)
    if cholesky:  # an indefinite matrix: a clear error, where an LU without pivoting would go on
        with pytest.raises(HeatcurvError, match="not positive definite"):
            point_laplacian.spd_factor(lap.first_order - 0.05 * sp.diags(lap.area))


def test_without_cvxopt_the_spectral_tools_give_the_same_numbers(random_sphere, monkeypatch):
    from heatcurv.operators import point_laplacian

    pts, _ = random_sphere
    fast = PointCloudLaplacian(pts)
    values, vectors = fast.eigenpairs(8)
    heat = fast.heat(pts[:, 2], time=0.05)
    distance = fast.geodesic_distance(7)
    monkeypatch.setattr(point_laplacian, "cholmod", None)
    plain = PointCloudLaplacian(pts)
    plain_values, plain_vectors = plain.eigenpairs(8)
    np.testing.assert_allclose(plain_values, values, rtol=1e-9, atol=1e-9)
    # eigenvectors up to a rotation within each degree: the same projector onto degrees 0-1 (4 vectors)
    np.testing.assert_allclose(plain_vectors[:, :4] @ (plain_vectors[:, :4].T * plain.area),
                               vectors[:, :4] @ (vectors[:, :4].T * fast.area), atol=1e-7)
    np.testing.assert_allclose(plain.heat(pts[:, 2], time=0.05), heat, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(plain.geodesic_distance(7), distance, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("steps_per_gamma", [0.5, 3.9, 4.0, 40.0])
def test_heat_steps_from_first_order_factors_equal_the_assembled_backward_euler(random_sphere, steps_per_gamma):
    # (A + tau S) factors into (A + a S1) A^-1 (A + b S1): real a, b from tau = 4 gamma on, complex below
    import scipy.sparse.linalg as spla

    pts, lap = random_sphere
    tau = steps_per_gamma * lap.gamma
    start = np.column_stack([pts[:, 2] ** 2, np.exp(pts[:, 0])])
    got = lap.heat(start, time=2 * tau, steps=2)
    direct = spla.splu((lap.mass + tau * lap.stiffness).tocsc())
    want = start
    for _ in range(2):
        want = direct.solve(lap.area[:, None] * want)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    assert got.dtype == np.float64


def test_heat_of_the_first_order_operator_is_one_factorisation(random_sphere):
    import scipy.sparse.linalg as spla

    pts, _ = random_sphere
    lap = PointCloudLaplacian(pts, order=1)
    assert lap.gamma == 0.0
    got = lap.heat(pts[:, 1], time=0.01)
    want = spla.splu((lap.mass + 0.01 * lap.first_order).tocsc()).solve(lap.area * pts[:, 1])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
