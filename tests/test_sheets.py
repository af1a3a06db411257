"""A ball holding the other side of a thin part: no area, not reliable."""

import numpy as np

import heatcurv
from heatcurv import surfaces
from heatcurv.neighbourhood import knn_neighbourhood
from heatcurv.sheets import second_sheet


def _two_sheets(gap, bottom_up, n=4000, seed=0):
    """Two random unit squares ``gap`` apart (z = 0 and z = gap) and their normals: top up, bottom down or up."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, 1.0, size=(n, 2))
    points = np.column_stack([xy, np.where(np.arange(n) < n // 2, gap, 0.0)])
    normals = np.zeros((n, 3))
    normals[:, 2] = np.where(np.arange(n) < n // 2, 1.0, 1.0 if bottom_up else -1.0)
    return points, normals


def _flags(points, normals):
    """The flags and the spacing ``h`` as the estimator has them: 60 neighbours, ``h = R / alpha`` (alpha 2)."""
    nbhd = knn_neighbourhood(points, 60)
    spacing = nbhd.radius / 2.0
    return second_sheet(points, normals, nbhd, spacing), float(np.median(spacing))


def _sheets_apart(gap, bottom_up):
    """The two squares ``gap`` spacings ``h`` apart (``h`` of one square alone) and their flags."""
    points, normals = _two_sheets(0.0, bottom_up)
    top = np.arange(len(points)) < len(points) // 2
    _, h = _flags(points[top], normals[top])
    points[top, 2] = gap * h
    return points, _flags(points, normals)[0]


def test_the_two_sides_of_a_plate_under_a_spacing_thick_are_flagged():
    # a point is flagged when a point of the other side lies within 45 degrees of its normal among its
    # 20 nearest and higher than h / 2: measured 99.4 % of the interior points at a gap of 0.75 h (98 %
    # at h / 2, 72 % at h, 14 % at 1.25 h, none at h / 4 and from 2.5 h)
    points, flagged = _sheets_apart(0.75, bottom_up=False)
    interior = np.all((points[:, :2] > 0.1) & (points[:, :2] < 0.9), axis=1)
    assert flagged[interior].mean() >= 0.98


def test_sheets_facing_the_same_way_are_not_flagged():
    # one over the other and facing alike, they look like one noisy sheet: noise scatters points over
    # each other with their normals alike, and is no reason to drop an area
    _, flagged = _sheets_apart(0.75, bottom_up=True)
    assert not flagged.any()


def test_a_noisy_sheet_and_sheets_far_apart_are_not():
    points, normals = _two_sheets(0.0, False)
    top = np.arange(len(points)) < len(points) // 2
    _, h = _flags(points[top], normals[top])
    # one sheet with noise of h / 2 across it: its points lie over each other, their normals alike
    noisy = points[top] + np.random.default_rng(1).normal(scale=[0.0, 0.0, h / 2], size=(top.sum(), 3))
    assert not _flags(noisy, normals[top])[0].any()
    # the two sides 3 h apart: beyond the 20 nearest (measured: 5 points flagged at 2 h, at the edges; none from 2.5 h)
    assert not _sheets_apart(3.0, bottom_up=False)[1].any()


def test_curved_resolved_surfaces_are_one_sheet():
    for name in ("sphere", "torus"):
        sample = surfaces.get(name).sample(5000, "random", seed=1)
        flagged, _ = _flags(sample.points, sample.normals)
        assert not flagged.any(), name


def test_a_thin_plate_gets_no_area_where_its_balls_hold_both_sides():
    # an ellipsoid 1 x 1 x 0.04 lying flat, oriented outward: where its balls hold both faces (near the
    # middle, where it is thickest in spacings) the points get no area and are not reliable
    sample = surfaces.Ellipsoid(1.0, 1.0, 0.04).sample(20000, "random", seed=0)
    result = heatcurv.estimate(sample.points)
    flagged = (result.area == 0) & ~result.outlier
    assert result.info["second_sheet"] == np.count_nonzero(flagged)
    assert not np.any(flagged & result.reliable)
    # measured: 23.2 % of the points flagged
    assert flagged.mean() >= 0.2


def test_noise_is_not_a_second_sheet():
    # a torus with noise of 0.3 and 0.6 % of its diagonal (about 1 and 2 neighbour distances): its points
    # scatter over and under each other, their normals stay alike (measured: none flagged)
    for noise in (0.003, 0.006):
        result = heatcurv.estimate(surfaces.Torus().sample(20000, "random", seed=0, noise=noise).points)
        assert result.info["second_sheet"] == 0
