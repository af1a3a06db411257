"""heatcurv.kernel_check: kernels that leave nothing to fit are refused, doubtful ones warned about."""

import warnings

import numpy as np
import pytest

import heatcurv
from heatcurv import HeatcurvError, HeatcurvWarning, surfaces
from heatcurv.kernel import effective_neighbours
from heatcurv.kernel_check import SUPPORT_LIMITS, measure_support
from heatcurv.neighbourhood import ball_neighbourhood, knn_neighbourhood
from heatcurv.operator import build_operator


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
    assert support.fit == "chord" and support.effective_neighbours > 3 * SUPPORT_LIMITS["chord"][1]
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
