"""heatcurv.operators.laplace_beltrami: the matrix (eq 2.9) applied to the coordinates is K (eq 2.10)."""

import numpy as np

from heatcurv.operators.laplace_beltrami import laplace_beltrami_matrix
from heatcurv.operators.mean_curvature import mean_curvature_normal
from heatcurv.operators.operator import build_operator


def test_laplacian_of_coordinates_is_the_mean_curvature_normal(sphere_sample):
    op = build_operator(sphere_sample.points)
    L = laplace_beltrami_matrix(op.neighbourhood, op.weights, op.areas, op.h, op.m)
    K = mean_curvature_normal(op.points, op.neighbourhood, op.weights, op.areas, op.h, op.m)
    np.testing.assert_allclose(L @ op.points, K, rtol=1e-9, atol=1e-9)
