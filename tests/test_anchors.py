"""heatcurv.anchors: wide kernels fitted at anchors with their whole balls, carried to every point."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import surfaces
from heatcurv.anchors import ANCHORS_PER_BALL, anchor_rows, carry_fits, fit_anchors
from heatcurv.areas import density_areas
from heatcurv.neighbourhood import knn_neighbourhood
from heatcurv.sampling import geometric_keys
from heatcurv.scale import Scale, fit_at_scale
from heatcurv.testing import compare


def _anchored(points, normals, k, denoise=False):
    tree = cKDTree(points)
    base = knn_neighbourhood(points, 60, tree=tree)
    areas = density_areas(base)
    keys = geometric_keys(points, base)
    index = anchor_rows(keys, np.full(points.shape[0], k))
    anchors = fit_anchors(points, tree, normals[index], areas, index, np.full(index.shape[0], k), denoise=denoise)
    return anchors, carry_fits(points, anchors), tree, areas


def test_anchors_are_about_per_ball_in_each_ball():
    pts = surfaces.Sphere().sample(20_000, "random", seed=1).points
    keys = geometric_keys(pts, knn_neighbourhood(pts, 60))
    for k in (480, 1920):
        index = anchor_rows(keys, np.full(len(pts), k))
        assert len(index) == pytest.approx(len(pts) * ANCHORS_PER_BALL / k, rel=0.15)
        assert np.all(np.diff(index) > 0)
    assert len(anchor_rows(keys, np.full(len(pts), 8))) == len(pts)  # narrower than per_ball: every point
    # wider kernels, sparser anchors, point by point
    k = np.where(pts[:, 0] < 0, 240, 1920)
    index = anchor_rows(keys, k)
    left = pts[index, 0] < 0
    assert left.sum() > 5 * (~left).sum()


def test_carrying_is_exact_on_a_sphere():
    # the chord model is exact on circles and the carried tensor is rotated into the point's
    # tangent plane: on a clean sphere every point gets 1/R from anchors up to half a ball away
    sample = surfaces.Sphere(radius=2.0).sample(20_000, "random", seed=2)
    anchors, carried, _, _ = _anchored(sample.points, sample.normals, 960)
    assert len(anchors.index) < 400
    np.testing.assert_allclose(carried.principal.k1, 0.5, atol=2e-4)
    np.testing.assert_allclose(carried.principal.k2, 0.5, atol=2e-4)
    cos = np.einsum("ij,ij->i", carried.normals, sample.normals)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.05
    assert carried.principal.well_posed.all()
    np.testing.assert_allclose(np.cross(carried.principal.d1, carried.principal.d2), carried.normals, atol=1e-12)


def test_carried_values_match_fits_at_every_point_on_a_graph():
    # z = .25 sin 2x sin 2y + .1 x^2: the curvature varies within a ball; carrying the anchors'
    # models (first order in the offset) stays close to fitting every point with the same kernel
    s, c = np.sin, np.cos
    graph = surfaces.Graph(
        lambda x, y: .25 * s(2 * x) * s(2 * y) + .1 * x * x, lambda x, y: .5 * c(2 * x) * s(2 * y) + .2 * x,
        lambda x, y: .5 * s(2 * x) * c(2 * y), lambda x, y: -s(2 * x) * s(2 * y) + .2,
        lambda x, y: c(2 * x) * c(2 * y), lambda x, y: -s(2 * x) * s(2 * y), size=1.5,
    )
    sample = graph.sample(20_000, "random", seed=3)
    _, carried, tree, areas = _anchored(sample.points, sample.normals, 480)
    inner = sample.interior(0.5)
    every, _, _ = fit_at_scale(sample.points, tree, sample.normals[inner], areas, Scale(480, False),
                               centres=np.flatnonzero(inner), passes=2)
    exact = sample.mean[inner]
    scale = np.abs(exact).mean()
    carried_error = np.abs(carried.principal.mean[inner] - exact).mean() / scale
    every_error = np.abs(every.principal.mean - exact).mean() / scale
    # measured: carried 1.09 %, every point 0.71 % (k = 240: 0.44 / 0.37 %, 960: 1.7 / 1.4 %): the
    # kernel's own bias dominates; carrying adds about 40 % of it (seeds 3-8: 1.28-1.52x, mean 1.41x;
    # with the sampling keys before the cloud-wide frame 1.21-1.63x, mean 1.43x: which anchors are
    # drawn moves the ratio by +-0.2)
    assert carried_error < 1.7 * every_error and carried_error < 0.012


def test_support_radius_bounds_what_a_point_depends_on():
    # the halo a tiled run needs: moving points beyond a point's support radius changes nothing at it
    sample = surfaces.Torus().sample(12_000, "random", seed=4, noise=0.004)
    res = heatcurv.estimate(sample.points, scale=960)
    report = res.info["scale"]
    assert report.anchors > 0 and np.isfinite(report.support_radius)
    assert report.support_radius < 2.0 * res.fit_radius.max()
    probe = int(np.argmin(np.linalg.norm(sample.points - sample.points[0], axis=1)))
    far = np.linalg.norm(sample.points - sample.points[probe], axis=1) > 3 * report.support_radius
    moved = sample.points.copy()
    moved[far] += np.random.default_rng(0).normal(scale=0.01, size=(far.sum(), 3))
    again = heatcurv.estimate(moved, scale=960)
    # (the scale choice and orientation are global; with scale fixed only the geometry near the probe matters)
    assert again.mean[probe] == pytest.approx(res.mean[probe], rel=1e-9)


def test_noisy_wide_kernels_use_the_whole_ball():
    # before: kernels wider than 240 neighbours averaged a random 240 of them (sphere 0.6 %: 3.8 %)
    sample = surfaces.Sphere().sample(20_000, "random", seed=1, noise=0.006)
    res = heatcurv.estimate(sample.points)
    errors = compare(sample, res)
    # measured: mean 1.0 %, k1 0.7 %, k2 1.7 % (denoised-3840)
    assert errors["rel_mean"] < 0.02 and errors["rel_k2"] < 0.03
    assert res.info["scale"].anchors > 0
    assert np.all(np.isfinite(res.mean)) and np.all(np.isfinite(res.normals))


def test_wide_neighbour_counts_work():
    # before: --neighbors above 240 failed with an internal error
    sample = surfaces.Sphere().sample(6000, "random", seed=2)
    res = heatcurv.estimate(sample.points, neighbours=480)
    assert res.info["scale"].k == 480
    assert np.median(res.mean) == pytest.approx(1.0, rel=2e-3)


def test_noise_that_swamps_the_small_balls_is_oriented_at_the_anchors():
    # noise 0.9 % of the diagonal on 20k torus points is 0.7 spacings: the operator's balls' PCA normals
    # were tilted by 24 degrees on average and 21 % of them pointed inward, all "reliable"
    sample = surfaces.Torus().sample(20_000, "random", seed=11, noise=0.009)
    res = heatcurv.estimate(sample.points)
    assert res.info["scale"].relative_noise > 0.5
    report = res.info["orientation"]
    assert report.on_anchors == res.info["scale"].anchors > 0
    errors = compare(sample, res)
    assert errors["orientation"] >= 0.995  # measured 100 %
    assert errors["normal_deg"] < 12  # measured 8.7 degrees (noise of 0.2 minor radii)
