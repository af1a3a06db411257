"""Error measures (heatcurv.testing.errors): zero on exact values, orientation-aware."""

from types import SimpleNamespace

import numpy as np
import pytest

from heatcurv import surfaces
from heatcurv.testing import aligned_exact, compare, default_margin, direction_error_deg, paper_error, relative_l1


def exact_result(sample, flip=False):
    s = -1.0 if flip else 1.0
    return SimpleNamespace(
        normals=s * sample.normals,
        mean=s * sample.mean,
        k1=-sample.k2 if flip else sample.k1,
        k2=-sample.k1 if flip else sample.k2,
        gaussian=sample.gaussian,
        d1=sample.d2 if flip else sample.d1,
        area=np.full(len(sample.points), sample.total_area / len(sample.points)),
        reliable=np.ones(len(sample.points), bool),
        spacing=np.full(len(sample.points), 0.01),
        options=SimpleNamespace(alpha=4.0),
    )


@pytest.mark.parametrize("flip", [False, True])
def test_exact_values_have_zero_error(flip):
    sample = surfaces.Saddle().sample(900, "grid")
    err = compare(sample, exact_result(sample, flip))
    assert aligned_exact(sample, exact_result(sample, flip))["flipped"] is flip
    for key in ("rel_mean", "rel_k1", "rel_k2", "rel_gaussian", "eq51_mean", "area"):
        assert err[key] == pytest.approx(0.0, abs=1e-12), key
    # arccos of a rounded 1.0 is ~1e-8 rad
    assert err["d1_deg"] < 1e-5 and err["normal_deg"] < 1e-5
    assert err["orientation"] == 1.0 and err["reliable"] == 1.0


def test_measures():
    assert relative_l1(np.array([1.1, 1.9]), np.array([1.0, 2.0])) == pytest.approx(0.2 / 3)
    assert np.isnan(relative_l1(np.ones(3), np.zeros(3)))
    assert paper_error(np.array([-1.0, 2.5]), np.array([1.0, 2.0])) == pytest.approx(0.25)
    a = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    b = np.array([[-1.0, 0, 0], [np.sqrt(0.5), np.sqrt(0.5), 0]])
    assert direction_error_deg(a, b) == pytest.approx(22.5)


def test_default_margin_without_the_alpha_coupling():
    sample = surfaces.Saddle().sample(900, "grid")
    result = exact_result(sample)  # a CurvatureResult-like: options.alpha = 4, spacing 0.01
    assert default_margin(result) == pytest.approx(4.0 * 0.01, rel=1e-15)
    assert np.array_equal(compare(sample, result)["interior"], sample.interior(4.0 * 0.01))
    # a result that states its own neighbourhood radius needs no options.alpha
    own = SimpleNamespace(**{k: v for k, v in vars(result).items() if k != "options"}, support_radius=0.3)
    assert default_margin(own) == 0.3
    assert np.array_equal(compare(sample, own)["interior"], sample.interior(0.3))
    # an explicit margin wins
    assert np.array_equal(compare(sample, own, margin=0.1)["interior"], sample.interior(0.1))
