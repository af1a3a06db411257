"""heatcurv.choice.kernel_check: kernels that leave nothing to fit are refused, doubtful ones warned about."""

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import HeatcurvError, HeatcurvWarning, surfaces
from heatcurv.choice.kernel_check import _ball_counts, _round_up, measure_support
from heatcurv.data import bunny_path
from heatcurv.geometry.neighbourhood import ball_neighbourhood, knn_neighbourhood
from heatcurv.io import read_points
from heatcurv.operators.kernel import effective_neighbours
from heatcurv.operators.operator import build_operator
from heatcurv.tuning import TUNING


@pytest.fixture(scope="module")
def random_sphere():
    return surfaces.Sphere().sample(5000, "random", seed=1).points


@pytest.fixture(scope="module")
def fibonacci_sphere():
    return surfaces.Sphere().sample(4000, "fibonacci").points


def test_effective_neighbours():
    pts = np.random.default_rng(0).random((200, 3))
    nb = knn_neighbourhood(pts, 10)
    np.testing.assert_allclose(effective_neighbours(nb, np.ones(nb.n_pairs)), 10.0)
    one_hot = np.tile(np.r_[1.0, np.zeros(9)], 200)  # all the weight on the nearest neighbour
    np.testing.assert_allclose(effective_neighbours(nb, one_hot), 1.0)
    np.testing.assert_array_equal(effective_neighbours(nb, np.zeros(nb.n_pairs)), 0.0)


def test_take_rows_is_the_subsample_of_the_rows():
    pts = np.random.default_rng(1).random((300, 3))
    nb = ball_neighbourhood(pts, 0.2, min_neighbours=3)
    rows = np.array([5, 0, 299, 17])
    sub = nb.take_rows(rows)
    for k, r in enumerate(rows):
        a, b = nb.indptr[r], nb.indptr[r + 1]
        np.testing.assert_array_equal(sub.indices[sub.indptr[k] : sub.indptr[k + 1]], nb.indices[a:b])
        np.testing.assert_array_equal(sub.distances[sub.indptr[k] : sub.indptr[k + 1]], nb.distances[a:b])
    np.testing.assert_array_equal(sub.radius, nb.radius[rows])


def test_the_presets_pass_silently_on_their_clouds(random_sphere, fibonacci_sphere):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = heatcurv.estimate(random_sphere)
        heatcurv.estimate(fibonacci_sphere, method="paper")
    assert "kernel_check" in res.info["timings"]
    op = build_operator(random_sphere)
    support = measure_support(op.neighbourhood, op.h, op.options)
    assert support.fit == "chord" and support.effective_neighbours > 3 * TUNING.chord_support[1]
    assert support.edge_weight == pytest.approx(np.exp(-4.0))  # alpha = 2: exp(-alpha^2)


@pytest.mark.parametrize("alpha", [10, 20])
def test_a_kernel_narrower_than_its_neighbours_is_an_error(random_sphere, alpha):
    # before: alpha = 20 gave a median mean curvature of 0.56 on the unit sphere, 1000 gave 0, exit 0
    # (alpha above 20 is now refused by the option's range, heatcurv.options)
    with pytest.raises(HeatcurvError, match=rf"alpha = {alpha}: the heat kernel is so narrow .* use alpha <= 6\.\d"):
        heatcurv.estimate(random_sphere, alpha=alpha)


def test_a_barely_supported_kernel_warns_and_names_the_range(random_sphere):
    with pytest.warns(HeatcurvWarning, match=r"alpha = 8: .* only 2\.\d+ effective neighbours.*use alpha <= 6\.\d"):
        res = heatcurv.estimate(random_sphere, alpha=8)
    np.testing.assert_allclose(np.median(res.mean), 1.0, rtol=1e-3)  # still right, and said to be noisy


def test_a_kernel_wider_than_its_ball_warns(random_sphere):
    with pytest.warns(HeatcurvWarning, match="wider than its ball"):
        heatcurv.estimate(random_sphere, alpha=0.5)


def test_paper_kernel_checks(fibonacci_sphere, random_sphere):
    # m = 0.1: mean curvature 33 % off with every point "reliable" before; now refused with the range
    with pytest.raises(HeatcurvError, match=r"alpha = 4, m = 0.1: .* tensor fit needs at least 5: use m >= 0\.2"):
        heatcurv.estimate(fibonacci_sphere, method="paper", m=0.1)
    # alpha = 2 cuts the kernel at exp(-4) = 1.8 % of its peak: the quadratures are biased (10 % here)
    with pytest.warns(HeatcurvWarning, match=r"cuts the heat kernel at 0.018 of its peak.*use alpha >= 2\.63"):
        heatcurv.estimate(fibonacci_sphere, method="paper", alpha=2)
    # the paper's own preset on a random cloud stays reproducible, with a warning
    with pytest.warns(HeatcurvWarning, match="method 'paper' does not suit this cloud"):
        heatcurv.estimate(random_sphere, method="paper")


@pytest.fixture(scope="module")
def bunny():
    return read_points(bunny_path()).points


def _ball_warnings(points, **options):
    """The messages of the ball-count warnings of ``estimate(points, **options)``, and the result."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = heatcurv.estimate(points, **options)
    return [str(w.message) for w in caught if "leaves a median point's ball" in str(w.message)], res


def test_a_radius_below_the_spacing_warns_and_names_one_that_works(bunny):
    # the bunny's points are 0.28 apart: a ball of 1e-4 holds none, every point got its 6 nearest and
    # came out unreliable, with no word of why
    messages, res = _ball_warnings(bunny, radius=1e-4)
    assert messages == [
        "radius = 0.0001 leaves a median point's ball with 0 neighbours; the chord fit has 9 unknowns and needs "
        "at least 10, so many points will be unreliable. The points' median spacing is 0.28: radius = 0.7 gives "
        "90 % of them at least 10 neighbours"
    ]
    assert res.reliable.sum() == 0
    # just short of enough: a median ball of 9 (18 % of the points reliable)
    messages, res = _ball_warnings(bunny, radius=0.6)
    assert len(messages) == 1 and messages[0].startswith("radius = 0.6 leaves a median point's ball with 9 neighbours;")
    # the radius it names: no warning, and 78 % of the points reliable (measured 1409 of 1839)
    messages, res = _ball_warnings(bunny, radius=0.7)
    assert messages == [] and res.reliable.sum() == 1409


def test_a_ball_of_alpha_spacings_that_holds_too_few_names_an_alpha(bunny):
    messages, _ = _ball_warnings(bunny, spacing="global", alpha=1.0)
    assert messages == [
        "alpha = 1 (global spacing) leaves a median point's ball with 1 neighbour; the chord fit has 9 unknowns and "
        "needs at least 10, so many points will be unreliable. The points' median spacing is 0.28: alpha = 2.5 "
        "gives 90 % of them at least 10 neighbours"
    ]
    assert _ball_warnings(bunny, spacing="global", alpha=2.5)[0] == []
    # min_neighbours asks for more than the fit: the ball must hold that many
    messages, res = _ball_warnings(bunny, spacing="global", alpha=2.0, min_neighbours=40)
    assert messages == [
        "alpha = 2 (global spacing) leaves a median point's ball with 8 neighbours; min_neighbours = 40 asks for "
        "at least 40 (a point with fewer gets its nearest ones), so many points will be unreliable. The points' "
        "median spacing is 0.28: alpha = 4.5 gives 90 % of them at least 40 neighbours"
    ]
    assert res.reliable.sum() == 0
    assert _ball_warnings(bunny, spacing="global", alpha=4.5, min_neighbours=40)[0] == []


def test_the_paper_fit_needs_min_neighbours_in_its_ball(bunny):
    messages, _ = _ball_warnings(bunny, method="paper", alpha=1.5, m=1.0)
    assert messages == [
        "alpha = 1.5 (global spacing) leaves a median point's ball with 5 neighbours; min_neighbours = 6 asks for "
        "at least 6 (a point with fewer gets its nearest ones), so many points will be unreliable. The points' "
        "median spacing is 0.28: alpha = 2 gives 90 % of them at least 6 neighbours"
    ]


def test_the_message_is_in_the_input_unit(bunny):
    messages, _ = _ball_warnings(bunny * 1e-12, radius=1e-16)  # computed in another unit (heatcurv.geometry.validation)
    assert len(messages) == 1
    assert "radius = 1e-16 leaves a median point's ball with 0 neighbours;" in messages[0]
    assert "median spacing is 2.8e-13: radius = 7e-13 gives 90 % of them" in messages[0]


def test_ball_counts_are_the_points_within_the_ball_also_where_augmented():
    pts = np.random.default_rng(2).random((500, 3))
    reach = np.random.default_rng(3).uniform(0.02, 0.2, 500)
    nb = ball_neighbourhood(pts, reach, min_neighbours=6)
    assert nb.augmented.sum() > 100  # the small balls got their nearest points
    within = cKDTree(pts).query_ball_point(pts, reach, return_length=True) - 1
    np.testing.assert_array_equal(_ball_counts(nb, reach), within)


def test_round_up_keeps_two_digits_and_never_rounds_down():
    assert [_round_up(x) for x in (0.695, 0.7, 2.4301, 0.01, 123.0)] == pytest.approx([0.7, 0.7, 2.5, 0.01, 130.0])
