"""The default estimator's stages: chord fit (chordfit), kernel choice (scale), border flags
(border), flat-top taper and density areas (kernel, areas)."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import surfaces
from heatcurv.areas import _taper_moments, ball_area_factor, density_areas
from heatcurv.border import BORDER_OFFSET, border_points, centroid_offset
from heatcurv.chordfit import chord_fit, segment_lstsq
from heatcurv.kernel import ball_taper, flat_top
from heatcurv.neighbourhood import Neighbourhood, ball_neighbourhood
from heatcurv.scale import Scale, fit_at_scale, select_scale


def test_segment_lstsq_matches_numpy_per_row():
    rng = np.random.default_rng(0)
    counts = rng.integers(8, 30, size=40)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    nnz = indptr[-1]
    nb = Neighbourhood(indptr, np.zeros(nnz, np.int32), np.ones(nnz), np.ones(40), np.zeros(40, bool))
    X, y, w = rng.normal(size=(nnz, 5)), rng.normal(size=nnz), rng.uniform(0.1, 2, nnz)
    beta, rss, ok, var = segment_lstsq(nb, X, y, w, contrast=np.array([1.0, 0, 0, 0, 1.0]))
    for i in (0, 17, 39):
        sl = slice(indptr[i], indptr[i + 1])
        sw = np.sqrt(w[sl])
        ref, *_ = np.linalg.lstsq(X[sl] * sw[:, None], y[sl] * sw, rcond=None)
        np.testing.assert_allclose(beta[i], ref, rtol=1e-7, atol=1e-9)
        assert rss[i] == pytest.approx(np.sum(w[sl] * (y[sl] - X[sl] @ ref) ** 2), rel=1e-6)
        # sandwich variance of c.beta for unit noise: c^T G^-1 X^T W^2 X G^-1 c
        G = X[sl].T @ (w[sl, None] * X[sl])
        u = np.linalg.solve(G, [1.0, 0, 0, 0, 1.0])
        assert var[i] == pytest.approx(u @ (X[sl].T @ (w[sl, None] ** 2 * X[sl])) @ u, rel=1e-6)
    assert ok.all()


def sphere_setup(n=3000, R=2.0, tilt_deg=0.0, seed=0):
    pts = surfaces.Sphere(radius=R).sample(n, "random", seed=seed).points
    tree = cKDTree(pts)
    d, _ = tree.query(pts, k=61)
    nb = ball_neighbourhood(pts, d[:, -1], tree=tree)
    normals = pts / R
    if tilt_deg:
        # tilt every normal by the same angle about a tangent axis
        axis = np.cross(normals, [0.3, 0.5, 0.81])
        axis /= np.linalg.norm(axis, axis=1)[:, None]
        t = np.radians(tilt_deg)
        normals = normals * np.cos(t) + np.cross(axis, normals) * np.sin(t)
    h = nb.radius / 2
    w = np.exp(-(nb.distances**2) / np.repeat(h, nb.counts) ** 2)
    return pts, nb, normals, w


def test_chord_fit_is_exact_on_a_sphere():
    pts, nb, normals, w = sphere_setup()
    fit = chord_fit(pts, nb, normals, w)
    # exact up to the solver's ridge (1e-10 of the normal matrix): measured 1e-6 relative
    np.testing.assert_allclose(fit.principal.mean, 0.5, rtol=1e-5)
    np.testing.assert_allclose(fit.principal.k1, 0.5, rtol=1e-5)
    np.testing.assert_allclose(fit.principal.k2, 0.5, rtol=1e-5)
    assert np.median(fit.sigma) < 1e-9


def test_tilt_terms_correct_a_wrong_normal():
    # normals tilted by 3 degrees: the first fit measures the tilt, the second works in the
    # corrected frame. Measured: 3 deg -> 0.0013 deg after two passes, mean error 4e-6
    pts, nb, normals, w = sphere_setup(tilt_deg=3.0)
    one = chord_fit(pts, nb, normals, w, passes=1)
    two = chord_fit(pts, nb, normals, w, passes=2)
    exact = pts / 2.0
    angle = lambda a: np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, exact), -1, 1)))
    assert np.median(angle(one.normals)) == pytest.approx(3.0, rel=1e-6)  # pass 1 reports its input
    assert np.median(angle(two.normals)) < 0.01
    assert np.abs(two.principal.mean - 0.5).max() < 1e-3
    without_tilt = chord_fit(pts, nb, normals, w, passes=1, tilt=False)
    # without the odd terms the tilt corrupts the curvature
    assert np.mean(np.abs(without_tilt.principal.mean - 0.5)) > 10 * np.mean(np.abs(two.principal.mean - 0.5))


def test_denoised_fit_estimates_the_noise():
    sample = surfaces.Sphere().sample(6000, "random", seed=1, noise=0.003)
    pts = sample.points
    tree = cKDTree(pts)
    d, _ = tree.query(pts, k=241)
    nb = ball_neighbourhood(pts, d[:, -1], tree=tree)
    w = np.exp(-(nb.distances**2) / np.repeat(nb.radius / 2, nb.counts) ** 2)
    fit = chord_fit(pts, nb, sample.normals, w, denoise=True, passes=1)
    # measured: sigma estimate 0.98 of the true noise, mean curvature error 1.9 %
    assert np.median(fit.sigma) == pytest.approx(sample.sigma, rel=0.15)
    assert np.mean(np.abs(fit.principal.mean - 1.0)) < 0.05
    chord = chord_fit(pts, nb, sample.normals, w, passes=1)
    assert np.mean(np.abs(chord.principal.mean - 1.0)) > 5 * np.mean(np.abs(fit.principal.mean - 1.0))


def test_select_scale_clean_and_noisy():
    for noise, expect_clean in [(0.0, True), (0.006, False)]:
        sample = surfaces.Torus().sample(8000, "random", seed=2, noise=noise)
        op = heatcurv.build_operator(sample.points)
        normals = sample.normals[op.prepared.first]
        choice = select_scale(op.points, op.tree, normals, op.areas)
        if expect_clean:
            assert choice.scale == Scale(60, False)
        else:
            assert choice.scale.denoise and choice.scale.k >= 480
            # measured 0.97 of the true noise
            assert choice.sigma == pytest.approx(sample.sigma, rel=0.2)
            assert choice.sd == sorted(choice.sd, reverse=True)  # wider kernels: less variance


def test_coarse_level_keeps_the_cost_bounded():
    sample = surfaces.Sphere().sample(8000, "random", seed=4, noise=0.003)
    op = heatcurv.build_operator(sample.points)
    nrm = sample.normals[op.prepared.first]
    fit, h, nb, fraction = fit_at_scale(op.points, op.tree, nrm, op.areas, Scale(960, True), k_fit=240)
    assert fraction == pytest.approx(0.25, rel=0.01)
    # about 240 coarse neighbours per ball instead of 960
    assert 200 < nb.counts.mean() < 280
    assert np.mean(np.abs(fit.principal.mean - 1.0)) < 0.05


def test_flat_top_and_taper():
    u = np.array([0.0, 0.5, 0.7, 0.85, 1.0, 1.2])
    np.testing.assert_allclose(flat_top(u), [1, 1, 1, 0.5, 0, 0], atol=1e-12)
    i1, i2 = _taper_moments()
    # int over the unit disc: between the cosine-tapered annulus' bounds
    assert np.pi * 0.7**2 < i1 < np.pi and i2 < i1
    pts = np.random.default_rng(0).random((300, 3))
    nb = ball_neighbourhood(pts, 0.2, min_neighbours=3)
    t = ball_taper(nb)
    assert np.all((t >= 0) & (t <= 1))


def test_density_areas_on_a_lattice_and_the_ball_factor():
    # a square grid with step s: areas s^2 in the interior (measured 0.2 % off)
    m, s = 41, 0.05
    x, y = np.meshgrid(np.arange(m) * s, np.arange(m) * s)
    pts = np.c_[x.ravel(), y.ravel(), np.zeros(m * m)]
    tree = cKDTree(pts)
    d, _ = tree.query(pts, k=61)
    nb = ball_neighbourhood(pts, d[:, -1], tree=tree)
    A = density_areas(nb).reshape(m, m)
    np.testing.assert_allclose(A[10:-10, 10:-10], s * s, rtol=0.01)
    # sphere: the ball cuts exactly pi R^2; cylinder radius 1: 1 + R^2 / 32
    assert ball_area_factor(np.array([0.5]), np.array([1.0]), np.array([1.0]))[0] == 1.0
    assert ball_area_factor(np.array([0.5]), np.array([1.0]), np.array([0.0]))[0] == pytest.approx(1 + 0.25 / 32)


def test_border_points_of_an_open_patch():
    sample = surfaces.Plane().sample(10000, "random", seed=5)
    pts = sample.points
    tree = cKDTree(pts)
    d, _ = tree.query(pts, k=61)
    nb = ball_neighbourhood(pts, d[:, -1], tree=tree)
    normals = np.tile([0, 0, 1.0], (len(pts), 1))
    offset = centroid_offset(pts, nb, normals, ball_taper(nb))
    flagged = border_points(pts, nb, normals, weights=ball_taper(nb))
    R = np.median(nb.radius)
    # every point on the border is flagged, no point deeper than one ball radius is
    edge = sample.border_distance < 0.05 * R
    assert flagged[edge].all()
    assert not flagged[sample.border_distance > R].any()
    assert np.median(offset[sample.border_distance > R]) < 0.1 < BORDER_OFFSET


def test_fitting_in_blocks_changes_nothing(monkeypatch):
    import heatcurv.neighbourhood as neighbourhood_module

    sample = surfaces.Torus().sample(3000, "random", seed=6)
    whole = heatcurv.estimate(sample.points)
    monkeypatch.setattr(neighbourhood_module, "BLOCK_PAIRS", 5000)  # the one block-size policy: about 80 blocks
    blocked = heatcurv.estimate(sample.points)
    for name in whole.FIELDS:
        np.testing.assert_allclose(getattr(blocked, name), getattr(whole, name), rtol=1e-12, atol=1e-12)


def test_row_blocks_cover_every_row_once():
    pts = np.random.default_rng(7).random((500, 3))
    nb = ball_neighbourhood(pts, 0.2, min_neighbours=3)
    blocks = list(nb.row_blocks(300))
    assert blocks[0][0] == 0 and blocks[-1][1] == 500
    assert all(b[1] == c[0] for b, c in zip(blocks, blocks[1:]))
    sub = nb.rows_slice(*blocks[1])
    np.testing.assert_array_equal(sub.counts, nb.counts[blocks[1][0] : blocks[1][1]])
