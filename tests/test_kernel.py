"""heatcurv.operators.kernel: heat-kernel weights and their normalisations (eqs 2.8, 2.9), the flat-top taper."""

import numpy as np
import pytest

from heatcurv import HeatcurvError
from heatcurv.geometry.neighbourhood import ball_neighbourhood
from heatcurv.operators.areas import _taper_moments
from heatcurv.operators.kernel import (
    area_normalisation,
    ball_taper,
    flat_top,
    heat_kernel_weights,
    laplacian_normalisation,
)


def test_heat_kernel_weights_and_normalisations():
    pts = np.random.default_rng(4).random((200, 3))
    nb = ball_neighbourhood(pts, 0.2, min_neighbours=3)
    h = np.full(200, 0.05)
    # m = 1/4: W = exp(-d^2/h^2), 1/(4 pi t) = 1/(pi h^2), 1/(4 pi t^2) = 4/(pi h^4)  (eqs 2.8, 2.9)
    np.testing.assert_allclose(heat_kernel_weights(nb, h, 0.25), np.exp(-nb.distances**2 / 0.05**2), rtol=1e-14)
    np.testing.assert_allclose(area_normalisation(h, 0.25), 1 / (np.pi * 0.05**2), rtol=1e-14)
    np.testing.assert_allclose(laplacian_normalisation(h, 0.25), 4 / (np.pi * 0.05**4), rtol=1e-14)
    # general m: t = m h^2
    np.testing.assert_allclose(heat_kernel_weights(nb, h, 0.5), np.exp(-nb.distances**2 / (2 * 0.05**2)), rtol=1e-14)
    with pytest.raises(HeatcurvError, match="m must be positive"):
        heat_kernel_weights(nb, h, 0.0)


def test_flat_top_and_taper():
    u = np.array([0.0, 0.5, 0.7, 0.85, 1.0, 1.2])
    np.testing.assert_allclose(flat_top(u), [1, 1, 1, 0.5, 0, 0], atol=1e-12)
    i1, i2 = _taper_moments()
    # int over the unit disc: between the cosine-tapered annulus' bounds
    assert np.pi * 0.7**2 < i1 < np.pi and i2 < i1
    # in closed form, W = (1 + cos(pi v / L)) / 2 on the annulus u = u0 + v, L = 1 - u0:
    # I1 = 2 pi (u0^2 / 2 + (1 - u0^2) / 4 - L^2 / pi^2), I2 = 2 pi (u0^2 / 2 + 3 (1 - u0^2) / 16 - L^2 / pi^2)
    for u0 in (0.7, 0.5):
        L2 = (1 - u0) ** 2 / np.pi**2
        exact = 2 * np.pi * np.array([u0**2 / 2 + (1 - u0**2) / 4 - L2, u0**2 / 2 + 3 * (1 - u0**2) / 16 - L2])
        np.testing.assert_allclose(_taper_moments(u0), exact, rtol=1e-14)  # Gauss-Legendre: measured 2.2e-16
    pts = np.random.default_rng(0).random((300, 3))
    nb = ball_neighbourhood(pts, 0.2, min_neighbours=3)
    t = ball_taper(nb)
    assert np.all((t >= 0) & (t <= 1))
