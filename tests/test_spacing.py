"""heatcurv.geometry.spacing: the spacing h, global (eq 2.6) and local (eq 2.7)."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from heatcurv import HeatcurvError
from heatcurv.geometry.spacing import global_spacing, local_spacing, spacing


def grid(m=21, step=0.1):
    x, y = np.meshgrid(np.arange(m) * step, np.arange(m) * step)
    return np.c_[x.ravel(), y.ravel(), np.zeros(m * m)]


def test_global_spacing_of_a_grid_is_its_step():
    # every grid point's nearest neighbour is one step away: eq 2.6 is exact
    assert global_spacing(grid(step=0.1)) == pytest.approx(0.1, rel=1e-12)


def test_global_spacing_is_the_mean_nearest_distance():
    pts = np.random.default_rng(0).random((300, 3))
    d = cdist(pts, pts)
    np.fill_diagonal(d, np.inf)
    assert global_spacing(pts) == pytest.approx(d.min(axis=1).mean(), rel=1e-12)


def test_local_spacing_eq_2_7():
    pts = np.random.default_rng(1).random((300, 3))
    d = np.sort(cdist(pts, pts), axis=1)[:, 1:]
    for gamma, k in [(0.0, 8), (0.3, 8), (1.0, 5)]:
        expect = (1 - gamma) * d[:, 0] + gamma * d[:, k - 1]
        np.testing.assert_allclose(local_spacing(pts, gamma=gamma, k=k), expect, rtol=1e-12)
    # interior grid point: nearest 1 step, 8th nearest sqrt(2) steps
    h = local_spacing(grid(step=0.1), gamma=0.25, k=8)
    centre = 10 * 21 + 10
    assert h[centre] == pytest.approx(0.1 * (0.75 + 0.25 * np.sqrt(2)), rel=1e-12)


def test_spacing_dispatch_and_errors():
    pts = grid()
    assert np.all(spacing(pts, "global") == global_spacing(pts))
    with pytest.raises(HeatcurvError, match="spacing must be"):
        spacing(pts, "median")
    with pytest.raises(HeatcurvError, match="gamma"):
        local_spacing(pts, gamma=1.5)
