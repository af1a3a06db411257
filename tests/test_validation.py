"""heatcurv.validation: bad input raises HeatcurvError naming it; duplicates and far coordinates are handled."""

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.validation import prepare_normals, prepare_points


@pytest.fixture(scope="module")
def small_sphere():
    return surfaces.Sphere().sample(1500, "fibonacci").points


def test_error_is_a_value_error():
    assert issubclass(HeatcurvError, ValueError)


@pytest.mark.parametrize(
    "points, words",
    [
        (np.zeros((10, 2)), "shape (n, 3)"),
        (np.zeros(30), "shape (n, 3)"),
        (np.zeros((4, 3, 1)), "shape (n, 3)"),
        (np.zeros((0, 3)), "empty"),
        ([["a", "b", "c"]] * 10, "numeric"),
    ],
)
def test_wrong_shape_or_type(points, words):
    with pytest.raises(HeatcurvError, match=words.replace("(", r"\(").replace(")", r"\)")):
        heatcurv.estimate(points)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_coordinates_name_the_rows(small_sphere, bad):
    pts = small_sphere.copy()
    pts[[3, 7], 1] = bad
    with pytest.raises(HeatcurvError, match=r"NaN or infinite.*2 row\(s\).*rows 3, 7"):
        heatcurv.estimate(pts)


def test_too_few_points():
    pts = np.random.default_rng(0).normal(size=(5, 3))
    with pytest.raises(HeatcurvError, match="too few points: 5 distinct"):
        heatcurv.estimate(pts)


def test_too_few_after_merging_duplicates():
    pts = np.repeat(np.random.default_rng(0).normal(size=(4, 3)), 10, axis=0)
    with pytest.raises(HeatcurvError, match="too few points: 4 distinct"):
        heatcurv.estimate(pts)


def test_coincident_points():
    with pytest.raises(HeatcurvError, match="all 50 points coincide"):
        heatcurv.estimate(np.tile([1.0, 2.0, 3.0], (50, 1)))


def test_collinear_points():
    t = np.linspace(0, 1, 100)[:, None]
    pts = 4e6 + t * np.array([[1.0, -2.0, 0.5]])
    with pytest.raises(HeatcurvError, match="lie on one line"):
        heatcurv.estimate(pts)


def test_bad_normals(small_sphere):
    with pytest.raises(HeatcurvError, match=r"normals must have shape \(1500, 3\)"):
        heatcurv.estimate(small_sphere, normals=small_sphere[:10])
    nrm = small_sphere.copy()
    nrm[5] = 0.0
    with pytest.raises(HeatcurvError, match="zero length"):
        heatcurv.estimate(small_sphere, normals=nrm)
    nrm[5] = np.nan
    with pytest.raises(HeatcurvError, match="NaN or infinite"):
        heatcurv.estimate(small_sphere, normals=nrm)


def test_prepare_points_centres_and_maps_back():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(50, 3)) + 1e6
    prep = prepare_points(pts)
    np.testing.assert_allclose(prep.points[prep.inverse] + prep.offset, pts, rtol=0, atol=1e-9)
    assert np.all(np.abs(prep.points) < 10)  # centred
    nrm = prepare_normals(rng.normal(size=(50, 3)), prep)
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0)


def test_duplicates_get_their_twins_values(small_sphere):
    rng = np.random.default_rng(2)
    twins = rng.choice(len(small_sphere), 40, replace=False)
    pts = np.concatenate([small_sphere, small_sphere[twins]])
    res = heatcurv.estimate(pts)
    ref = heatcurv.estimate(small_sphere)
    assert len(res) == len(pts)
    assert res.info["n_distinct"] == len(small_sphere)
    n = len(small_sphere)
    for name in ("mean", "gaussian", "k1", "k2", "normals"):
        got = getattr(res, name)
        np.testing.assert_allclose(got[n:], got[twins], rtol=0, atol=0)
        np.testing.assert_allclose(got[:n], getattr(ref, name), rtol=1e-12, atol=1e-12)
    # a point and its twin share its area, so the total stays the surface area
    np.testing.assert_allclose(res.area.sum(), ref.area.sum(), rtol=1e-12)
    np.testing.assert_allclose(res.area[twins] + res.area[n:], ref.area[twins], rtol=1e-12)


@pytest.mark.parametrize("offset", [5e5, 4e6, 1e7])
def test_far_coordinates_give_the_centred_results(offset, small_sphere):
    # UTM-like coordinates: centring first keeps xi - xj exact to ~1e-9
    # relative to the offset, i.e. ~1e-3 of a spacing at 1e7 m; curvature
    # changes stay below 1e-6 relative.
    ref = heatcurv.estimate(small_sphere)
    far = heatcurv.estimate(small_sphere + np.array([offset, -0.7 * offset, 0.3 * offset]))
    np.testing.assert_allclose(far.mean, ref.mean, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(far.k1, ref.k1, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(far.area, ref.area, rtol=1e-6)
    np.testing.assert_allclose(far.normals, ref.normals, atol=1e-6)


def test_signed_zeros_are_one_point_and_distinct_clouds_keep_their_order():
    rng = np.random.default_rng(7)
    pts = rng.uniform(-1, 1, size=(200, 3))
    pts[0], pts[1] = -1.0, 1.0  # bounding box centred at 0: the offset is exactly 0
    prep = prepare_points(pts)
    assert prep.n_distinct == 200 and np.array_equal(prep.points, pts)  # no duplicates: input order
    twins = np.vstack([pts, [[-0.0, 0.5, 0.25], [0.0, 0.5, 0.25]]])
    prep = prepare_points(twins)
    assert prep.n_distinct == 201
    assert prep.inverse[200] == prep.inverse[201]


def test_reordered_points_map_back_to_input_rows():
    rng = np.random.default_rng(1)
    pts = rng.random((500, 3))
    pts = np.vstack([pts, pts[:7]])  # duplicates
    prep = prepare_points(pts)
    order = rng.permutation(prep.n_distinct)
    moved = prep.reordered(order)
    np.testing.assert_array_equal(moved.points[moved.inverse] + moved.offset, pts)
    np.testing.assert_array_equal(moved.first, prep.first[order])
    area = rng.random(prep.n_distinct)
    assert moved.share_among_duplicates(area[order]).sum() == pytest.approx(area.sum(), rel=1e-12)
