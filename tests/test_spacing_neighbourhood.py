"""Spacing h (eqs 2.6, 2.7), ball neighbourhoods in CSR form, heat-kernel weights (eq 2.8)."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from heatcurv import HeatcurvError, surfaces
from heatcurv.kernel import area_normalisation, heat_kernel_weights, laplacian_normalisation
from heatcurv.neighbourhood import ball_neighbourhood
from heatcurv.spacing import global_spacing, local_spacing, spacing


def grid(m=21, step=0.1):
    x, y = np.meshgrid(np.arange(m) * step, np.arange(m) * step)
    return np.c_[x.ravel(), y.ravel(), np.zeros(m * m)]


def test_global_spacing_of_a_grid_is_its_step():
    # every grid point's nearest neighbour is one step away: eq 2.6 is exact
    assert global_spacing(grid(step=0.1)) == pytest.approx(0.1, rel=1e-12)


def test_global_spacing_is_the_mean_nearest_distance():
    pts = np.random.default_rng(0).random((300, 3))
    d = cdist(pts, pts)
    np.fill_diagonal(d, np.inf)
    assert global_spacing(pts) == pytest.approx(d.min(axis=1).mean(), rel=1e-12)


def test_local_spacing_eq_2_7():
    pts = np.random.default_rng(1).random((300, 3))
    d = np.sort(cdist(pts, pts), axis=1)[:, 1:]
    for gamma, k in [(0.0, 8), (0.3, 8), (1.0, 5)]:
        expect = (1 - gamma) * d[:, 0] + gamma * d[:, k - 1]
        np.testing.assert_allclose(local_spacing(pts, gamma=gamma, k=k), expect, rtol=1e-12)
    # interior grid point: nearest 1 step, 8th nearest sqrt(2) steps
    h = local_spacing(grid(step=0.1), gamma=0.25, k=8)
    centre = 10 * 21 + 10
    assert h[centre] == pytest.approx(0.1 * (0.75 + 0.25 * np.sqrt(2)), rel=1e-12)


def test_spacing_dispatch_and_errors():
    pts = grid()
    assert np.all(spacing(pts, "global") == global_spacing(pts))
    with pytest.raises(HeatcurvError, match="spacing must be"):
        spacing(pts, "median")
    with pytest.raises(HeatcurvError, match="gamma"):
        local_spacing(pts, gamma=1.5)


def test_ball_neighbourhood_matches_brute_force():
    pts = np.random.default_rng(2).random((400, 3))
    r = 0.15
    nb = ball_neighbourhood(pts, r, min_neighbours=3)
    d = cdist(pts, pts)
    for i in (0, 17, 399):
        expect = np.flatnonzero((d[i] <= r) & (np.arange(400) != i))
        got = nb.indices[nb.indptr[i] : nb.indptr[i + 1]]
        if not nb.augmented[i]:
            np.testing.assert_array_equal(got, expect)
    rows = nb.rows
    np.testing.assert_allclose(nb.distances, d[rows, nb.indices], rtol=1e-12)
    assert not np.any(rows == nb.indices)  # the point itself is not stored
    full = ~nb.augmented
    # symmetric for a scalar radius: j in B(i) <=> i in B(j) (among non-augmented points)
    pairs = set(zip(rows[full[rows] & full[nb.indices]].tolist(), nb.indices[full[rows] & full[nb.indices]].tolist()))
    assert all((j, i) in pairs for i, j in pairs)


def test_isolated_points_get_their_nearest_neighbours():
    pts = np.vstack([grid(11, 0.1), [[5.0, 5.0, 1.0]]])
    nb = ball_neighbourhood(pts, 0.15, min_neighbours=6)
    assert nb.augmented[-1] and nb.counts[-1] == 6
    # interior grid points have 8 neighbours within 0.15 and are left alone; corners (3) are augmented
    assert not nb.augmented[12] and nb.counts[12] == 8
    assert nb.augmented[0] and nb.counts[0] == 6
    far = nb.indices[nb.indptr[-2] : nb.indptr[-1]]
    d = np.linalg.norm(pts[:-1] - pts[-1], axis=1)
    np.testing.assert_array_equal(np.sort(far), np.sort(np.argsort(d)[:6]))


def test_segment_sum_and_counts():
    pts = np.random.default_rng(3).random((100, 3))
    nb = ball_neighbourhood(pts, 0.3, min_neighbours=3)
    ones = nb.segment_sum(np.ones(nb.n_pairs))
    np.testing.assert_array_equal(ones, nb.counts)
    assert nb.n_points == 100 and nb.indptr[-1] == nb.n_pairs


def test_heat_kernel_weights_and_normalisations():
    pts = np.random.default_rng(4).random((200, 3))
    nb = ball_neighbourhood(pts, 0.2, min_neighbours=3)
    h = np.full(200, 0.05)
    # m = 1/4: W = exp(-d^2/h^2), 1/(4 pi t) = 1/(pi h^2), 1/(4 pi t^2) = 4/(pi h^4)  (eqs 2.8, 2.9)
    np.testing.assert_allclose(heat_kernel_weights(nb, h, 0.25), np.exp(-nb.distances**2 / 0.05**2), rtol=1e-14)
    np.testing.assert_allclose(area_normalisation(h, 0.25), 1 / (np.pi * 0.05**2), rtol=1e-14)
    np.testing.assert_allclose(laplacian_normalisation(h, 0.25), 4 / (np.pi * 0.05**4), rtol=1e-14)
    # general m: t = m h^2
    np.testing.assert_allclose(heat_kernel_weights(nb, h, 0.5), np.exp(-nb.distances**2 / (2 * 0.05**2)), rtol=1e-14)
    with pytest.raises(HeatcurvError, match="m must be positive"):
        heat_kernel_weights(nb, h, 0.0)


def test_ball_holds_the_expected_number_of_points_on_a_sphere():
    # a ball of chord radius r cuts a cap of area exactly pi r^2 from a unit sphere, so
    # each of the n - 1 other points of an area-uniform random sample lies in it with
    # probability r^2 / 4
    n = 4000
    pts = surfaces.Sphere().sample(n, "random", seed=5).points
    r = 0.2
    nb = ball_neighbourhood(pts, r)
    # the mean of 4000 correlated counts of ~40: relative std well below 1 %
    assert nb.counts.mean() == pytest.approx((n - 1) * r**2 / 4, rel=0.01)
