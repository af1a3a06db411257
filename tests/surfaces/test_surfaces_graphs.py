"""Tests of heatcurv.surfaces.graphs: Monge-patch formulas, the sign convention at special points, areas.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate
from surfaces_helpers import CASES, GRAPH_CASES, GRAPH_FUNCS, random_params

from heatcurv import surfaces as hs


@pytest.mark.parametrize("case", GRAPH_CASES)
def test_graph_monge_formulas(case):
    surf = CASES[case]()
    u, v = random_params(surf, n=200, seed=5)
    _, fx, fy, fxx, fxy, fyy = (g(u, v) for g in GRAPH_FUNCS[case])
    w2 = 1 + fx**2 + fy**2
    mean = -((1 + fy**2) * fxx - 2 * fx * fy * fxy + (1 + fx**2) * fyy) / (2 * w2**1.5)
    gauss = (fxx * fyy - fxy**2) / w2**2
    c = surf.curvature(u, v)
    assert np.allclose(c.mean, mean, rtol=1e-13, atol=1e-14)
    assert np.allclose(c.gaussian, gauss, rtol=1e-12, atol=1e-14)


def test_curvature_signs_and_special_values():
    # upward-opening paraboloid bends toward its upward normal: negative, -2a
    c = hs.Paraboloid(a=0.5).curvature([0.0], [0.0])
    assert c.k1[0] == pytest.approx(-1.0) and c.k2[0] == pytest.approx(-1.0) and c.umbilic[0]
    c = hs.Saddle(a=0.5).curvature([0.0], [0.0])
    assert (c.k1[0], c.k2[0], c.gaussian[0]) == pytest.approx((1.0, -1.0, -1.0))
    assert np.allclose(np.abs(c.d1[0]), [0, 1, 0])  # k1 = +2a along y
    x = np.linspace(-1, 1, 11)
    c = hs.Arch(a=0.5).curvature(x, 0 * x)
    assert np.allclose(c.k1, 1.0 / (1 + x**2) ** 1.5, rtol=1e-14)
    assert np.all(c.k2 == 0) and np.all(c.gaussian == 0)
    c = hs.Cylinder(radius=0.8).curvature([0.3], [0.1])
    assert (c.k1[0], c.k2[0], c.mean[0]) == pytest.approx((1.25, 0.0, 0.625))
    assert np.allclose(c.d2, [[0, 0, 1]])


@pytest.mark.parametrize("case", GRAPH_CASES)
def test_graph_area_against_dblquad_of_fd_area_element(case):
    surf = CASES[case]()
    s = surf.size
    h = 1e-5  # central FD: truncation ~h^2 |X'''| ~1e-10, rounding ~eps/h ~1e-11

    def element(y, x):
        p = surf.position([x + h, x - h, x, x], [y, y, y + h, y - h])
        xu = (p[0] - p[1]) / (2 * h)
        xv = (p[2] - p[3]) / (2 * h)
        return float(np.linalg.norm(np.cross(xu, xv)))

    ref, err = integrate.dblquad(element, -s, s, -s, s, epsabs=0, epsrel=1e-11)
    assert surf.area() == pytest.approx(ref, rel=1e-8)
