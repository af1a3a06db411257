"""Error measures (heatcurv.surfaces.accuracy): zero on exact values, orientation-aware."""

from types import SimpleNamespace

import numpy as np
import pytest

from heatcurv import surfaces
from heatcurv.surfaces.accuracy import (
    aligned_exact,
    compare,
    default_margin,
    direction_error_deg,
    neighbour_margin,
    paper_error,
    relative_l1,
)


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
    # atan2 resolves the rounding of unit vectors (~1e-16 rad), where arccos of a rounded 1.0 gives ~1e-8 rad
    assert err["d1_deg"] < 1e-12 and err["normal_deg"] < 1e-12
    assert err["orientation"] == 1.0 and err["reliable"] == 1.0
    assert (~err["interior"]).sum() > 100  # a border band is judged too, and is exact here
    for key in ("border_rel_mean", "border_rel_k1", "border_rel_k2"):
        assert err[key] == pytest.approx(0.0, abs=1e-12), key
    assert err["border_d1_deg"] < 1e-12 and err["border_normal_deg"] < 1e-12


def test_the_border_band_is_judged_apart():
    sample = surfaces.Saddle().sample(900, "grid")
    result = exact_result(sample)
    margin = neighbour_margin(sample.points)
    # the sampling's own scale: at the border's worst points (corners) 40 neighbours fill a quarter disc
    # of radius sqrt(4 * 40 / pi) = 7.1 steps of the 30 x 30 grid (step 2/29, stretched by the saddle's slope)
    assert 6 * 2 / 29 < margin < 7.5 * 2 / 29
    band = ~sample.interior(margin)
    result.mean = result.mean + np.where(band, 0.01, 0.0)  # an error at the border only
    err = compare(sample, result, margin=margin)
    assert err["rel_mean"] == pytest.approx(0.0, abs=1e-12)
    exact = np.abs(sample.mean[band]).mean()
    assert err["border_rel_mean"] == pytest.approx(0.01 / exact, rel=1e-9)
    closed = surfaces.Sphere().sample(500, "fibonacci")
    assert np.isnan(compare(closed, exact_result(closed))["border_rel_mean"])


def test_measures():
    assert relative_l1(np.array([1.1, 1.9]), np.array([1.0, 2.0])) == pytest.approx(0.2 / 3)
    assert np.isnan(relative_l1(np.ones(3), np.zeros(3)))
    assert paper_error(np.array([-1.0, 2.5]), np.array([1.0, 2.0])) == pytest.approx(0.25)
    a = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    b = np.array([[-1.0, 0, 0], [np.sqrt(0.5), np.sqrt(0.5), 0]])
    assert direction_error_deg(a, b) == pytest.approx(22.5)
    tiny = np.radians(1e-9)  # a nanodegree: arccos would report 0 or ~1e-6 deg
    c = np.array([[np.cos(tiny), np.sin(tiny), 0.0]])
    assert direction_error_deg(a[:1], c) == pytest.approx(1e-9, rel=1e-6)


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
