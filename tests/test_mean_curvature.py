"""heatcurv.operators.mean_curvature: chord normal curvatures of the edges, and kappa_M from K (eqs 2.11, 2.12)."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.geometry.neighbourhood import ball_neighbourhood
from heatcurv.operators.mean_curvature import edge_normal_curvatures, mean_curvature


def test_edge_normal_curvatures_are_exact_on_a_sphere():
    # the chord formula kN = 2 (xi-xj).n/|xi-xj|^2 is exact for two points of a circle
    pts = surfaces.Sphere(radius=3.0).sample(500, "fibonacci").points
    nb = ball_neighbourhood(pts, 0.8)
    kN = edge_normal_curvatures(pts, nb, pts / 3.0)
    np.testing.assert_allclose(kN, 1 / 3.0, rtol=1e-12)


def test_mean_curvature_formulas():
    K = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, -4.0]])
    n = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(mean_curvature(K, n, "projection"), [1.0, -2.0])
    np.testing.assert_allclose(mean_curvature(K, n, "norm"), [1.0, -2.5])
    with pytest.raises(heatcurv.HeatcurvError, match="eq 2.12"):
        mean_curvature(K, n, "average")
