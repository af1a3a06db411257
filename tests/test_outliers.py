"""heatcurv.flags.outliers: stray points and islands are flagged, get area 0, and leave the surface alone."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.flags.outliers import exceeds_neighbour_median, find_outliers, neighbour_medians
from heatcurv.geometry.neighbourhood import Neighbourhood, knn_neighbourhood


def _sphere_with_strays(seed=0):
    """A 6000-point unit sphere, 12 single points 0.4-2 off it, and 3 islands of 15 points 3 away."""
    rng = np.random.default_rng(seed)
    sphere = surfaces.Sphere().sample(6000, "random", seed=seed).points
    directions = rng.normal(size=(12, 3))
    singles = directions / np.linalg.norm(directions, axis=1)[:, None] * rng.uniform(1.4, 3.0, (12, 1))
    islands = np.vstack([rng.normal(scale=0.02, size=(15, 3)) + centre for centre in ([4.0, 0, 0], [0, -4.0, 0],
                                                                                       [0, 0, 4.0])])
    return np.vstack([sphere, singles, islands]), 6000


@pytest.mark.parametrize("sampler", ["random", "fibonacci", "jittered"])
def test_a_clean_surface_has_no_outlier(sampler):
    pts = surfaces.Torus().sample(8000, sampler, seed=1).points
    assert find_outliers(pts, knn_neighbourhood(pts, 60)).count == 0


def test_an_anisotropic_scan_has_no_outlier():
    # 40 scan lines, 16 times denser along than across: every line is its own component of the
    # 10-nearest graph, but the mutual-neighbour graph over the ball spans them
    t = np.linspace(0, 2 * np.pi, 640, endpoint=False)
    lat = np.linspace(-1.4, 1.4, 40)
    pts = np.array([[np.cos(b) * np.cos(a), np.cos(b) * np.sin(a), np.sin(b)] for b in lat for a in t])
    found = find_outliers(pts, knn_neighbourhood(pts, 60))
    assert found.count == 0


def test_single_points_and_islands_are_found():
    pts, n_surface = _sphere_with_strays()
    found = find_outliers(pts, knn_neighbourhood(pts, 60))
    assert found.mask[n_surface:].all()
    assert not found.mask[:n_surface].any()
    assert found.detached[n_surface + 12 :].all()  # the islands are smaller than a ball


def test_a_veil_of_sparse_points_is_found(records):
    # mixed pixels: a sparse cloud of points hanging off a dense plane, 9 times sparser per point
    rng = np.random.default_rng(3)
    plane = np.c_[rng.uniform(-1, 1, (20000, 2)), np.zeros(20000)]
    veil = np.c_[rng.uniform(0.9, 1.1, 150), rng.uniform(-1, 1, 150), rng.uniform(0.02, 0.3, 150)]
    pts = np.vstack([plane, veil])
    found = find_outliers(pts, knn_neighbourhood(pts, 60))
    # the veil's points nearest the plane pass
    records.check(
        "outliers/plane-veil-20150", veil_missed=100 * (1 - found.mask[20000:].mean()),
        plane_flagged=100 * found.mask[:20000].mean(),
    )


def test_estimate_gives_outliers_area_zero_and_keeps_the_surface_area(records):
    pts, n_surface = _sphere_with_strays(1)
    res = heatcurv.estimate(pts)
    assert res.outlier[n_surface:].all() and not res.outlier[:n_surface].any()
    assert not res.reliable[res.outlier].any()
    np.testing.assert_array_equal(res.area[res.outlier], 0.0)
    assert res.info["outliers"] == len(pts) - n_surface
    # the strays weigh nothing in the fit: the sphere's curvature is as without them; and the sphere's area,
    # strays excluded
    clean = heatcurv.estimate(pts[:n_surface])
    records.check(
        "outliers/sphere-random-6000-strays", area=100 * (res.area.sum() / (4 * np.pi) - 1),
        median_mean_vs_clean=100 * (np.median(res.mean[:n_surface]) / np.median(clean.mean) - 1),
    )


def test_far_outlier_does_not_turn_a_sphere_inside_out(records):
    # one point far away used to drag the outward vote; it is an outlier now and the sphere stays outward
    sphere = surfaces.Sphere().sample(2000, "fibonacci")
    res = heatcurv.estimate(np.vstack([sphere.points, [[25.0, 0, 0]]]))
    assert res.outlier[-1] and not res.outlier[:-1].any()
    assert np.all(np.einsum("ij,ij->i", res.normals[:-1], sphere.normals) > 0)
    records.check("outliers/sphere-fibonacci-2000-far-point", median_mean=100 * (np.median(res.mean[:-1]) - 1))


def test_neighbour_medians_match_numpy():
    rng = np.random.default_rng(9)
    values = rng.random(300)
    counts = rng.integers(0, 9, 300)
    indptr = np.r_[0, np.cumsum(counts)]
    nbhd = Neighbourhood(indptr=indptr, indices=rng.integers(0, 300, indptr[-1]).astype(np.int32),
                         distances=rng.random(indptr[-1]), radius=np.ones(300), augmented=np.zeros(300, bool))
    want = [np.median(values[nbhd.indices[a:b]]) if b > a else np.nan for a, b in zip(indptr[:-1], indptr[1:])]
    np.testing.assert_allclose(neighbour_medians(values, nbhd), want)
    uniform = knn_neighbourhood(rng.random((200, 3)), 7)  # rows of one length: the reshape path
    want = [np.median(values[uniform.indices[a:b]]) for a, b in zip(uniform.indptr[:-1], uniform.indptr[1:])]
    np.testing.assert_allclose(neighbour_medians(values, uniform), want)


@pytest.mark.parametrize("seed", range(4))
def test_exceeding_the_neighbour_median_without_the_median(seed):
    # rows of 0-9 neighbours (odd, even, empty), many ties and values on both sides of 3x the median
    rng = np.random.default_rng(seed)
    values = np.round(rng.lognormal(sigma=0.8, size=400) * 4.0) / 4.0 + 0.25
    counts = rng.integers(0, 10, 400)
    indptr = np.r_[0, np.cumsum(counts)]
    nbhd = Neighbourhood(indptr=indptr, indices=rng.integers(0, 400, indptr[-1]).astype(np.int32),
                         distances=rng.random(indptr[-1]), radius=np.ones(400), augmented=np.zeros(400, bool))
    # the definition, by numpy's median (exceeds_neighbour_median itself takes neighbour_medians for its ties)
    rows = zip(indptr[:-1], indptr[1:])
    medians = np.array([np.median(values[nbhd.indices[a:b]]) if b > a else np.nan for a, b in rows])
    for factor in (1.0, 2.0, 3.0):
        want = values > factor * medians
        assert np.array_equal(exceeds_neighbour_median(values, factor, nbhd), want)
        assert 0 < want.sum() < 400
