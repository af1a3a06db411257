"""heatcurv.geometry.validation: bad input raises HeatcurvError naming it; duplicates, far coordinates handled."""

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.geometry.validation import prepare_normals, prepare_points


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
        (np.ones((100, 3), dtype=complex), "real numbers, got complex ones"),
        (np.ones((100, 3), dtype=bool), "booleans"),
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


# ----------------------------------------------------------------- extreme coordinates
@pytest.fixture(scope="module")
def unit_sphere_result():
    pts = heatcurv.surfaces.Sphere().sample(2000, "random", seed=3).points
    return pts, heatcurv.estimate(pts)


@pytest.mark.parametrize("exponent", [-130, -100, -60, -13, 13, 60, 100, 130])
def test_extreme_scales_give_the_scaled_answer(unit_sphere_result, exponent):
    # before: 1e80-1e152 gave 49 % inward normals and means off by 10 %, 1e155 crashed (SIGSEGV)
    pts, ref = unit_sphere_result
    s = 10.0**exponent
    res = heatcurv.estimate(pts * s)
    # a power-of-two unit keeps the arithmetic exact up to the one rounding of pts * s
    assert np.allclose(res.mean * s, ref.mean, rtol=1e-9, atol=1e-12)
    assert np.allclose(res.gaussian * s * s, ref.gaussian, rtol=1e-9, atol=1e-12)
    assert np.allclose(res.area / (s * s), ref.area, rtol=1e-9)
    assert np.allclose(res.spacing / s, ref.spacing, rtol=1e-9)
    assert np.allclose(res.normals, ref.normals, atol=1e-9)
    assert res.info["scale"].median_radius == pytest.approx(ref.info["scale"].median_radius * s, rel=1e-9)
    assert np.array_equal(res.reliable, ref.reliable)


@pytest.mark.parametrize("s", [1e-150, 1e150, 1e300, 1e-300])
def test_extents_beyond_double_precision_are_refused(unit_sphere_result, s):
    pts, _ = unit_sphere_result
    with pytest.raises(HeatcurvError, match=r"the cloud spans .* outside the range .* rescale the coordinates"):
        heatcurv.estimate(pts * s)


def test_coordinates_near_the_largest_double_are_refused_not_overflowed():
    pts = heatcurv.surfaces.Sphere().sample(200, "random", seed=3).points
    with pytest.raises(HeatcurvError, match="outside the range"):
        heatcurv.estimate(pts * 1.5e308)


def test_extreme_scale_viewpoint_radius_and_laplacian_follow_the_unit():
    pts = heatcurv.surfaces.Sphere().sample(1500, "fibonacci").points
    s = 1e90
    res = heatcurv.estimate(pts * s, viewpoint=[0.0, 0.0, 10 * s])
    top = pts[:, 2] > 0.5
    assert np.all(res.normals[top, 2] > 0)  # facing the viewpoint, read in input units
    fixed = heatcurv.estimate(pts * s, radius=0.3 * s)
    assert np.median(fixed.mean) * s == pytest.approx(1.0, rel=1e-3)
    L, area = heatcurv.laplacian(pts * s)
    L1, area1 = heatcurv.laplacian(pts)
    assert np.allclose(area / s**2, area1, rtol=1e-9)
    assert np.allclose((L * s**2).toarray(), L1.toarray(), rtol=1e-9, atol=1e-9 * abs(L1).max())


def test_a_cloud_too_far_out_to_resolve_is_refused():
    pts = heatcurv.surfaces.Sphere().sample(500, "random", seed=3).points
    with pytest.raises(HeatcurvError, match="subtract a nearby origin"):
        heatcurv.estimate(pts + 1e15)


@pytest.mark.parametrize("n, values", [(2000, 12), (50_000, 40), (1000, None)])
def test_distinct_rows_are_numpys_unique_rows_in_order_of_first_occurrence(n, values):
    from heatcurv.geometry.validation import distinct_rows

    rng = np.random.default_rng(n)
    # a few values per coordinate: many repeated rows (none when values is None)
    points = rng.integers(0, values, (n, 3)).astype(float) if values else rng.normal(size=(n, 3))
    first, inverse = distinct_rows(points)
    _, unique_first = np.unique(points, axis=0, return_index=True)
    np.testing.assert_array_equal(first, np.sort(unique_first))
    np.testing.assert_array_equal(points[first][inverse], points)


def test_distinct_rows_tell_different_rows_of_one_hash_apart():
    from heatcurv.geometry.validation import distinct_rows

    # two different rows built to share the 64-bit hash (a c0 + b c1 + c c2, then an invertible xor-shift):
    # b' = (a c0 + b c1 - a' c0) / c1 mod 2^64
    c0, c1, mask = 0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, (1 << 64) - 1
    row = np.array([1.5, -2.25, 3.0])
    a, b = (int(x) for x in row[:2].view(np.uint64))
    for a2 in range(a + 1, a + 100):
        b2 = ((a * c0 + b * c1 - a2 * c0) * pow(c1, -1, 1 << 64)) & mask
        twin = np.array([a2, b2, int(row[2:].view(np.uint64)[0])], dtype=np.uint64).view(np.float64)
        if np.isfinite(twin).all():
            break
    points = np.array([row, twin, row, [0.0, 0.0, 0.0], twin])
    first, inverse = distinct_rows(points)
    np.testing.assert_array_equal(first, [0, 1, 3])
    np.testing.assert_array_equal(inverse, [0, 1, 0, 2, 1])
