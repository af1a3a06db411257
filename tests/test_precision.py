"""The precision of the input coordinates: float32 and grid-rounded (LAS) points too coarse for their curvature.

A value is "off" when it differs from the estimate of the same points before rounding (float64) by more
than ``TUNING.precision_tolerance`` of the point's curvature scale (the larger of ``|k1|``, ``|k2|`` and
``TUNING.flat_curvature / fit radius``), in ``k1``, ``k2`` or the mean curvature. Where the rounding changes
the fit's form or anchors, values move by the fit's own error: the tolerance is then
:data:`STANDARD_ERRORS` of the value's standard errors (docs/robustness.md).
"""


import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.errors import HeatcurvError
from heatcurv.flags.reliability import coordinate_rounding, imprecise
from heatcurv.tuning import TUNING


def off(rounded, exact) -> np.ndarray:
    """Points whose curvatures the rounding moved by more than the tolerance, shape (n,), bool."""
    scale = np.maximum(np.maximum(np.abs(exact.k1), np.abs(exact.k2)), TUNING.flat_curvature / exact.fit_radius)
    moved = np.maximum.reduce([np.abs(rounded.k1 - exact.k1), np.abs(rounded.k2 - exact.k2),
                               np.abs(rounded.mean - exact.mean)])
    return moved > TUNING.precision_tolerance * scale


def standard_errors_moved(rounded, exact) -> np.ndarray:
    """How far the rounding moved each point's mean, k1 or k2, the most, in standard errors of the difference
    (the two estimates' combined), shape (n,)."""
    return np.maximum.reduce([
        np.abs(getattr(rounded, name) - getattr(exact, name))
        / np.hypot(getattr(rounded, f"{name}_se"), getattr(exact, f"{name}_se"))
        for name in ("mean", "k1", "k2")
    ])


@pytest.fixture(scope="module")
def torus_2k():
    return surfaces.Torus(r1=1.0, r2=3.0).sample(2000, "random", seed=1).points


@pytest.fixture(scope="module")
def torus_2k_exact(torus_2k):
    return heatcurv.estimate(torus_2k)


def test_coordinate_rounding_by_type_and_option():
    rng = np.random.default_rng(0)
    single = rng.normal(size=(50, 3)).astype(np.float32) * 100
    half, source = coordinate_rounding(single)
    assert source == "float32 coordinates" and half.shape == (50, 3)
    np.testing.assert_array_equal(half, np.spacing(np.abs(single)).astype(np.float64) / 2)
    # a float64 array of float32 values is the same cloud
    half64, source64 = coordinate_rounding(single.astype(np.float64))
    assert source64 == "float64 values float32 holds exactly"
    np.testing.assert_array_equal(half64, half)
    # a float64 sample is exact; a list of them too; integers unless told otherwise
    assert coordinate_rounding(rng.normal(size=(50, 3))) is None
    assert coordinate_rounding(rng.normal(size=(50, 3)).tolist()) is None
    assert coordinate_rounding(np.arange(150).reshape(50, 3)) is None
    assert coordinate_rounding(np.arange(150).reshape(50, 3), 1)[0].tolist() == [0.5, 0.5, 0.5]
    # given: half the grid's step, per axis
    half, source = coordinate_rounding(single, 0.01)
    assert source == "coordinate_precision" and half.tolist() == [0.005, 0.005, 0.005]
    assert coordinate_rounding(single, [0.01, 0.01, 0.001])[0].tolist() == [0.005, 0.005, 0.0005]
    assert coordinate_rounding(single, 0) is None  # exact: no auto detection either


@pytest.mark.parametrize("value, problem", [
    (-0.01, r"must be finite and at least 0 \(the step of the grid .*\), got -0.01$"),
    (float("nan"), r"must be finite and at least 0"),
    ([0.01, 0.01], r"must be a number or three \(one per axis\), got shape \(2,\)"),
    ("fine", r"must be a number or three \(one per axis\), got 'fine'"),
])
def test_bad_coordinate_precision_is_refused_before_the_work(value, problem):
    with pytest.raises(HeatcurvError, match=problem):
        heatcurv.estimate(np.zeros((3, 3)), coordinate_precision=value)  # the points would fail later


def test_imprecise_judges_nearly_flat_points_against_the_ball():
    sigma = np.full(3, 1e-3)  # 5 sigma = 0.005
    k1, k2 = np.array([1.0, 0.0, 0.0]), np.array([-0.2, 0.0, 0.0])
    radius = np.array([1.0, 0.01, 1.0])
    # under 1 % of |k1| = 1; flat: under 1 % of 0.03 / R = 3 (R = 0.01), over 1 % of 0.03 (R = 1)
    assert imprecise(sigma, k1, k2, radius).tolist() == [False, False, True]


def test_float64_clouds_are_not_touched(torus_2k, torus_2k_exact):
    assert "precision" not in torus_2k_exact.info
    exact = heatcurv.estimate(torus_2k, coordinate_precision=0)
    for name in ("normals", "mean", "k1", "k2", "area", "reliable"):
        np.testing.assert_array_equal(getattr(exact, name), getattr(torus_2k_exact, name), err_msg=name)


def test_float32_input_is_float64_of_the_same_values_reliable_included(torus_2k):
    single = (torus_2k + 1e4).astype(np.float32)
    narrow, wide = heatcurv.estimate(single), heatcurv.estimate(single.astype(np.float64))
    for name in ("mean", "k1", "k2", "reliable"):
        np.testing.assert_array_equal(getattr(narrow, name), getattr(wide, name), err_msg=name)
    assert narrow.info["precision"].flagged == wide.info["precision"].flagged > 0
    np.testing.assert_array_equal(narrow.info["precision"].uncertainty, wide.info["precision"].uncertainty)


def test_a_torus_on_a_coarse_grid_is_unreliable_where_the_rounding_moves_it(torus_2k, torus_2k_exact):
    # a LAS file of quantum 0.01 holding a torus of tube radius 1 sampled with 2000 points (spacing 0.2)
    grid = np.round(torus_2k / 0.01) * 0.01
    unaware = heatcurv.estimate(grid)  # float64 values: taken as exact
    aware = heatcurv.estimate(grid, coordinate_precision=0.01)
    moved = off(aware, torus_2k_exact)
    # 1159 points off by up to 6 % of their curvature, every one of them reliable unless the grid is known
    assert int(moved.sum()) == 1159 and int((moved & unaware.reliable).sum()) == 1159
    assert not (moved & aware.reliable).any()
    report = aware.info["precision"]
    assert report.source == "coordinate_precision" and report.largest_error == 0.005
    assert report.flagged == 2000 and "2000 point(s) unreliable" in report.reason


@pytest.mark.parametrize("offset, n_off, n_flagged", [(1e3, 7, 190), (1e4, 596, 2000)])
def test_float32_far_from_the_origin_is_unreliable_where_the_rounding_moves_it(torus_2k, offset, n_off, n_flagged):
    # float32 rounds a coordinate by up to 2^-24 of its size: 6e-5 at 1000, 5e-4 at 10 000 units
    far = torus_2k + offset
    exact, single = heatcurv.estimate(far), heatcurv.estimate(far.astype(np.float32))
    moved = off(single, exact)
    assert int(moved.sum()) == n_off and not (moved & single.reliable).any()
    assert single.info["precision"].flagged == n_flagged


@pytest.mark.parametrize("offset, n_flagged", [(0.0, 32), (1e3, 0)])
def test_a_well_sampled_float32_torus_keeps_its_reliability(offset, n_flagged):
    # nothing is off by 1 %: the points flagged at the origin have a neighbour much nearer than the spacing,
    # which the chord fit's centre term counts at its worst (their measured change is below 0.15 %)
    far = surfaces.Torus(r1=1.0, r2=3.0).sample(20000, "random", seed=1).points + offset
    exact, single = heatcurv.estimate(far), heatcurv.estimate(far.astype(np.float32))
    assert not off(single, exact).any()
    assert single.info["precision"].flagged == n_flagged


def test_the_papers_method_reports_the_precision_it_does_not_assess():
    sphere = surfaces.Sphere(radius=2.0).sample(4000, "fibonacci").points  # a regular sample: the paper's case
    res = heatcurv.estimate((sphere + 1e3).astype(np.float32), method="paper")
    report = res.info["precision"]
    assert report.source == "float32 coordinates" and report.flagged == 0
    assert "not assessed by method='paper'" in report.reason and np.isnan(report.uncertainty).all()


PROPERTY_SURFACES = {"torus": surfaces.Torus, "paraboloid": surfaces.Paraboloid, "saddle": surfaces.Saddle,
                     "sphere": lambda: surfaces.Sphere(radius=1.0)}
#: The rounding may move a reliable value by 1 % of its scale or by this many standard errors of the move
#: (the rounded and the exact estimates' combined).
STANDARD_ERRORS = 5.0


@pytest.mark.parametrize("kind, sampler, seed, exponent, n_reliable_off", [
    ("torus", "random", 20436, 3, 783),
    ("torus", "fibonacci", 54244, 4, 1932),
    ("paraboloid", "random", 36018, 1, 10),
    ("saddle", "fibonacci", 19870, 2, 79),
])
def test_float32_property_clouds_keep_no_point_off_by_the_tolerance_reliable(kind, sampler, seed, exponent,
                                                                             n_reliable_off):
    # the clouds of the float32 property (tests/fuzz/test_fuzz_properties.py), 10**exponent sizes from the
    # origin; benchmarks/precision.py measures all of them. These keep the float64 fit's form and anchors:
    # where the rounding changes those, the values move by the fit's own error, which the flag cannot see
    points = PROPERTY_SURFACES[kind]().sample(2000, sampler, noise=0.0, seed=seed).points
    far = points + float(np.linalg.norm(np.ptp(points, axis=0))) * 10.0**exponent
    single = far.astype(np.float32)
    exact, rounded = heatcurv.estimate(far), heatcurv.estimate(single)
    assert (rounded.info["scale"].fit, rounded.info["scale"].anchors) == (exact.info["scale"].fit,
                                                                          exact.info["scale"].anchors)
    moved = off(rounded, exact)
    assert int((moved & heatcurv.estimate(single, coordinate_precision=0).reliable).sum()) == n_reliable_off
    assert not (moved & rounded.reliable).any()


def test_the_standard_errors_of_a_clean_float32_cloud_hold_its_rounding():
    # a float64 sphere is fitted exactly (errors near 1e-9 of the curvature); in float32 at 10 sizes from the
    # origin the rounding alone leaves errors of about 3e-5, noise the clean fit's residual does not measure.
    # The centre point's own rounding moves the chord fit's curvatures the most, and its gain is counted at
    # its worst: the bars are conservative here
    sphere = surfaces.Sphere(radius=1.0).sample(2000, "random", seed=3)
    exact = heatcurv.estimate(sphere.points + 10.0)
    single = heatcurv.estimate((sphere.points + 10.0).astype(np.float32))
    reliable = single.reliable
    assert single.info["scale"].fit == "chord-60" and reliable.sum() == 1970
    for name in ("mean", "k1", "k2"):
        error = np.abs(getattr(single, name) - getattr(sphere, name))[reliable]
        se = getattr(single, f"{name}_se")[reliable]
        # measured: 99.8 %, 98.1 %, 98.5 % within 2 standard errors; median bar 2.5x, 2.3x, 2.2x the median error
        assert np.mean(error < 2 * se) > 0.97, name
        assert 1.8 < np.median(se) / np.median(error) < 3.2, name
        assert np.median(getattr(exact, f"{name}_se")) < 1e-3 * np.median(se), name


@pytest.mark.parametrize("kind, sampler, noise, seed, n_reliable_off", [
    ("torus", "random", 0.0, 16333, 547),
    ("sphere", "random", 0.003, 62289, 586),
])
def test_where_the_rounding_changes_the_fit_values_move_within_their_standard_errors(kind, sampler, noise, seed,
                                                                                   n_reliable_off):
    # 574 and 2000 points at 1000 sizes from the origin (benchmarks/precision.py): the rounding changes the
    # fit's form or anchors, so reliable values move by the fit's own error, more than 1 % of their scale,
    # but (measured: at most 2.5 and 2.0) by less than the tolerance of 5 standard errors of the move
    n = 574 if noise == 0.0 else 2000
    points = PROPERTY_SURFACES[kind]().sample(n, sampler, noise=noise, seed=seed).points
    far = points + float(np.linalg.norm(np.ptp(points, axis=0))) * 1e3
    exact, rounded = heatcurv.estimate(far), heatcurv.estimate(far.astype(np.float32))
    assert (rounded.info["scale"].fit, rounded.info["scale"].anchors) != (exact.info["scale"].fit,
                                                                          exact.info["scale"].anchors)
    moved = off(rounded, exact)
    assert int((moved & rounded.reliable).sum()) == n_reliable_off
    assert not (moved & rounded.reliable & (standard_errors_moved(rounded, exact) > STANDARD_ERRORS)).any()


#: The float32 property's clouds (tests/fuzz/test_fuzz_properties.py, its derandomized examples): kind, points,
#: sampler, noise, seed, offset (10**offset sizes from the origin), points off by 1 % of their scale and reliable.
FLOAT32_PROPERTY_CLOUDS = [
    ("sphere", 300, "random", 0.0, 0, 0.0, 0),
    ("torus", 1024, "random", 0.001, 6509, 0.0681849876522982, 0),
    ("torus", 322, "random", 0.003, 56921, 0.09617622398268202, 0),
    ("paraboloid", 3000, "random", 0.0, 90, 2.673164642154911, 1),
    ("sphere", 573, "random", 0.001, 13507, 1.2855979031712785, 3),
    ("paraboloid", 1906, "random", 0.003, 65536, 0.14887292280259337, 149),
    ("torus", 341, "random", 0.001, 2149, 2.1357080544265024e-212, 0),
    ("paraboloid", 583, "random", 0.003, 65535, 2.7627332744009343, 424),
]


@pytest.mark.parametrize("kind, n, sampler, noise, seed, offset, n_reliable_off", FLOAT32_PROPERTY_CLOUDS)
def test_no_reliable_value_of_the_float32_property_clouds_moves_beyond_its_tolerance(kind, n, sampler, noise, seed,
                                                                                     offset, n_reliable_off):
    # on noisy clouds the rounding moves the sampling keys, so values move by their noise: by more than 1 % of
    # their scale, within their standard errors (measured: at most 4.8, on the clean paraboloid whose
    # float32 copy the kernel choice took for noisy)
    points = PROPERTY_SURFACES[kind]().sample(n, sampler, noise=noise, seed=seed).points
    far = points + float(np.linalg.norm(np.ptp(points, axis=0))) * 10.0**offset
    exact, rounded = heatcurv.estimate(far), heatcurv.estimate(far.astype(np.float32))
    moved = off(rounded, exact) & rounded.reliable
    assert int(moved.sum()) == n_reliable_off
    assert not (moved & (standard_errors_moved(rounded, exact) > STANDARD_ERRORS)).any()
