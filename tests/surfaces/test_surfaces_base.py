"""Tests of heatcurv.surfaces.base: the generic geometry of Surface checked against finite differences, the
inverse parametrisation, border distances, sample_at and SurfaceSample.transformed.

Every exact quantity is verified independently of the module's own derivative
code: the derivatives of the parametrisation are recomputed here from
``position`` alone by 4th-order central finite differences, the normal is
oriented by an independent geometric test, and the shape operator
``S = -I^{-1} II`` is diagonalised with ``numpy.linalg.eig``.

Finite-difference error budget (positions are O(1..3)):

* first derivatives, 4th-order stencil, h = 1e-3: truncation ~ h^4/30 |X^(5)|
  ~ 1e-13, rounding ~ 1.5 eps |X| / h ~ 1e-12;
* second derivatives (incl. the tensor-product mixed one), h = 5e-3:
  truncation ~ h^4/90 |X^(6)| <~ 1.5e-10 (|X^(6)| <~ 20 for the wavy graph),
  rounding ~ 5 eps |X| / h^2 ~ 1.5e-10.

So FD curvatures are good to ~1e-9; we assert 1e-7 (relative to max(1, |k|)),
and principal directions (error ~ dS / gap) to 1e-6 where the gap k1-k2 > 1e-2.
Measured worst cases over all surfaces: curvatures 2.6e-10, directions 1e-10,
normals 6e-13, so the assertions keep a margin of a few hundred.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from surfaces_helpers import CASES, GRAPH_FUNCS, random_params, residual, wavy_graph

from heatcurv import surfaces as hs
from heatcurv.errors import HeatcurvError


def outward_reference(surf, p):
    """Independent orientation reference vector for each surface (shape (n, 3))."""
    if isinstance(surf, hs.Sphere):
        return p - surf.centre
    if isinstance(surf, hs.Ellipsoid):
        return p  # star-shaped about the origin: p . n >= min(a, b, c) > 0
    if isinstance(surf, hs.Torus):
        rho = np.hypot(p[:, 0], p[:, 1])
        centre = surf.r2 * np.column_stack([p[:, 0] / rho, p[:, 1] / rho, 0 * rho])
        return p - centre
    if isinstance(surf, hs.Cylinder):
        return np.column_stack([p[:, 0], p[:, 1], 0 * p[:, 0]])
    return np.tile([0.0, 0.0, 1.0], (len(p), 1))  # graphs, plane, fold: upward


H1, H2 = 1e-3, 5e-3


C1 = {-2: 1 / 12, -1: -8 / 12, 1: 8 / 12, 2: -1 / 12}


C2 = {-2: -1 / 12, -1: 16 / 12, 0: -30 / 12, 1: 16 / 12, 2: -1 / 12}


def fd_geometry(surf, u, v):
    """FD derivatives, oriented normal and shape operator from ``position`` only."""
    P = surf.position
    xu = sum(c * P(u + k * H1, v) for k, c in C1.items()) / H1
    xv = sum(c * P(u, v + k * H1) for k, c in C1.items()) / H1
    xuu = sum(c * P(u + k * H2, v) for k, c in C2.items()) / H2**2
    xvv = sum(c * P(u, v + k * H2) for k, c in C2.items()) / H2**2
    xuv = sum(
        ci * cj * P(u + i * H2, v + j * H2) for i, ci in C1.items() for j, cj in C1.items()
    ) / H2**2
    n = np.cross(xu, xv)
    n /= np.linalg.norm(n, axis=1)[:, None]
    ref = outward_reference(surf, P(u, v))
    s = np.einsum("ij,ij->i", n, ref)
    # the reference must be far from tangent for the orientation to mean anything
    assert np.all(np.abs(s) > 0.1 * np.linalg.norm(ref, axis=1))
    n *= np.sign(s)[:, None]
    first = np.stack(
        [
            np.stack([np.einsum("ij,ij->i", xu, xu), np.einsum("ij,ij->i", xu, xv)], -1),
            np.stack([np.einsum("ij,ij->i", xv, xu), np.einsum("ij,ij->i", xv, xv)], -1),
        ],
        -2,
    )
    second = np.stack(
        [
            np.stack([np.einsum("ij,ij->i", xuu, n), np.einsum("ij,ij->i", xuv, n)], -1),
            np.stack([np.einsum("ij,ij->i", xuv, n), np.einsum("ij,ij->i", xvv, n)], -1),
        ],
        -2,
    )
    shape = -np.linalg.solve(first, second)
    evals, evecs = np.linalg.eig(shape)
    evals, evecs = evals.real, evecs.real
    order = np.argsort(-evals, axis=1)
    evals = np.take_along_axis(evals, order, 1)
    evecs = np.take_along_axis(evecs, order[:, None, :], 2)
    dirs = [
        evecs[:, 0, j, None] * xu + evecs[:, 1, j, None] * xv for j in range(2)
    ]
    dirs = [d / np.linalg.norm(d, axis=1)[:, None] for d in dirs]
    return dict(
        xu=xu, xv=xv, xuu=xuu, xuv=xuv, xvv=xvv, n=n,
        k1=evals[:, 0], k2=evals[:, 1],
        mean=0.5 * np.trace(shape, axis1=1, axis2=2),
        gaussian=np.linalg.det(second) / np.linalg.det(first),
        d1=dirs[0], d2=dirs[1],
    )


def same_up_to_sign(a, b):
    return np.minimum(np.linalg.norm(a - b, axis=1), np.linalg.norm(a + b, axis=1))


@pytest.mark.parametrize("case", sorted(CASES))
def test_tangents_normals_and_second_derivatives_match_fd(case):
    surf = CASES[case]()
    u, v = random_params(surf)
    fd = fd_geometry(surf, u, v)
    xu, xv = surf.tangents(u, v)
    xuu, xuv, xvv = surf.second_derivatives(u, v)
    # first derivatives: FD error ~1e-12 (see module docstring)
    assert np.max(np.abs(xu - fd["xu"])) < 1e-9
    assert np.max(np.abs(xv - fd["xv"])) < 1e-9
    # second derivatives: FD error ~3e-10
    for exact, key in ((xuu, "xuu"), (xuv, "xuv"), (xvv, "xvv")):
        assert np.max(np.abs(exact - fd[key])) < 1e-7
    n = surf.normal(u, v)
    assert n.dtype == np.float64 and n.shape == (50, 3)
    assert np.max(np.abs(n - fd["n"])) < 1e-9  # same orientation, not just same line


@pytest.mark.parametrize("case", sorted(CASES))
def test_curvature_matches_fd_shape_operator(case):
    surf = CASES[case]()
    u, v = random_params(surf)
    fd = fd_geometry(surf, u, v)
    c = surf.curvature(u, v)
    for key in ("k1", "k2", "mean", "gaussian"):
        exact = getattr(c, key)
        scale = np.maximum(1.0, np.abs(exact))
        assert exact.shape == (50,) and exact.dtype == np.float64
        assert np.max(np.abs(exact - fd[key]) / scale) < 1e-7, key
    gap = fd["k1"] - fd["k2"]
    ok = gap > 1e-2
    assert not np.any(c.umbilic & ok)
    if np.any(ok):
        assert np.max(same_up_to_sign(c.d1[ok], fd["d1"][ok])) < 1e-6
        assert np.max(same_up_to_sign(c.d2[ok], fd["d2"][ok])) < 1e-6
    umbilic_surface = case.startswith(("sphere", "plane", "folded"))
    assert np.all(c.umbilic) == umbilic_surface
    assert np.any(ok) == (not umbilic_surface)


@pytest.mark.parametrize("case", sorted(CASES))
def test_generic_formula_agrees_with_closed_form(case):
    surf = CASES[case]()
    u, v = random_params(surf, seed=1)
    a = surf.curvature(u, v)
    b = surf.curvature_from_derivatives(u, v)
    for key in ("k1", "k2", "mean", "gaussian"):
        # both exact up to rounding
        assert np.allclose(getattr(a, key), getattr(b, key), rtol=1e-12, atol=1e-12), key
    ok = ~a.umbilic
    assert np.array_equal(a.umbilic, b.umbilic)
    assert np.all(same_up_to_sign(a.d1[ok], b.d1[ok]) < 1e-12)


def border_curve(surf, k=4000):
    """Dense points on the border curve(s), from ``position`` only."""
    (u0, u1), (v0, v1) = surf.domain
    t = np.linspace(0, 1, k)
    if isinstance(surf, hs.Cylinder):
        uu = np.concatenate([u0 + (u1 - u0) * t] * 2)
        vv = np.concatenate([np.full(k, v0), np.full(k, v1)])
    else:
        su, sv = u0 + (u1 - u0) * t, v0 + (v1 - v0) * t
        uu = np.concatenate([su, su, np.full(k, u0), np.full(k, u1)])
        vv = np.concatenate([np.full(k, v0), np.full(k, v1), sv, sv])
    return surf.position(uu, vv)


@pytest.mark.parametrize("case", ["paraboloid", "wavy", "plane", "cylinder", "folded_60"])
def test_border_distance_is_a_lower_bound(case):
    surf = CASES[case]()
    smp = surf.sample(500, "random", seed=6)
    # Euclidean 3-D distance to the border is itself <= the distance along the surface
    euclid = cKDTree(border_curve(surf)).query(smp.clean_points)[0]
    assert np.all(smp.border_distance <= euclid + 1e-12)
    assert np.all(smp.border_distance >= 0)
    if case in ("plane", "cylinder", "folded_60"):
        # exact there: the nearest border point lies on the same straight ruling,
        # so surface and 3-D distance agree; the discretised border adds at most
        # half its spacing (<= 0.63e-3 for the cylinder, the coarsest)
        assert np.max(euclid - smp.border_distance) < 1e-3
    margin = 0.2
    assert np.array_equal(smp.interior(margin), smp.border_distance > margin)
    assert 0 < smp.interior(margin).sum() < len(smp)


def test_closed_surfaces_have_no_border():
    for surf in (hs.Sphere(), hs.Ellipsoid(), hs.Torus()):
        smp = surf.sample(100, "random", seed=0)
        assert np.all(np.isinf(smp.border_distance)) and np.all(smp.interior(10.0))
        assert np.all(np.isinf(smp.feature_distance)) and not np.any(smp.near_feature(1.0))


def test_sample_at_and_custom_graph():
    surf = wavy_graph()
    u = np.array([0.0, 0.5, -1.0])
    v = np.array([0.2, -0.3, 1.2])
    smp = surf.sample_at(u, v)
    assert smp.sampler == "custom" and len(smp) == 3
    assert np.array_equal(smp.clean_points, surf.position(u, v))
    assert np.allclose(smp.border_distance, [1.0, 0.7, 0.0])
    assert np.array_equal(smp.k1, surf.curvature(u, v).k1)
    noisy = surf.sample_at(u, v, noise=0.1, seed=0)
    assert noisy.sigma > 0 and not np.array_equal(noisy.points, noisy.clean_points)
    # scalars are length-1 arrays; callables may return scalars (broadcast)
    assert hs.Plane().position(0.5, 0.25).shape == (1, 3)
    bad = hs.Graph(*(lambda x, y: np.zeros(2) for _ in range(6)))
    with pytest.raises(HeatcurvError, match="shape"):
        bad.position(np.zeros(3), np.zeros(3))
    with pytest.raises(HeatcurvError):
        hs.Graph(1.0, *GRAPH_FUNCS["wavy"][1:])


@pytest.mark.parametrize("case", sorted(CASES))
def test_parameters_of_inverts_position(case):
    surf = CASES[case]()
    u, v = random_params(surf, n=500, seed=7)
    p = surf.position(u, v)
    u2, v2 = surf.parameters_of(p)
    assert np.max(np.abs(surf.position(u2, v2) - p)) < 1e-12
    for t, t2, (t0, t1), per in zip((u, v), (u2, v2), surf.domain, surf.periodic):
        diff = t2 - t
        if per:
            diff = (diff + (t1 - t0) / 2) % (t1 - t0) - (t1 - t0) / 2
        assert np.max(np.abs(diff)) < 1e-10
    # also on the border, the seams and near the poles
    smp = surf.sample(400, "grid")
    uu, vv = surf.parameters_of(smp.clean_points)
    assert np.max(np.abs(surf.position(uu, vv) - smp.clean_points)) < 1e-12
    (u0, u1), _ = surf.domain
    if surf.periodic[0]:
        assert np.all((uu >= u0) & (uu < u1))


def test_transformed_sample():
    rng = np.random.default_rng(2)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    rot = q * np.sign(np.diag(r))
    if np.linalg.det(rot) < 0:
        rot[:, 0] *= -1
    shift = np.array([3e6, -1e7, 5e6])
    surf = hs.Ellipsoid()
    smp = surf.sample(500, "random", noise=0.01, seed=3)
    tr = smp.transformed(100.0, rot, shift)
    assert np.allclose(tr.clean_points, 100 * smp.clean_points @ rot.T + shift, rtol=0, atol=1e-8)
    assert np.allclose(tr.points - tr.clean_points, 100 * (smp.points - smp.clean_points) @ rot.T, atol=1e-8)
    # the moved points lie on the moved ellipsoid, the rotated normals are its normals
    back = (tr.clean_points - shift) @ rot / 100
    assert np.max(np.abs(residual("ellipsoid", surf, back))) < 1e-9
    assert np.allclose(tr.normals, smp.normals @ rot.T, atol=1e-15)
    assert np.allclose(np.cross(tr.d1, tr.d2), tr.normals, atol=1e-14)
    assert np.allclose(tr.mean, smp.mean / 100) and np.allclose(tr.gaussian, smp.gaussian / 1e4)
    assert np.all(tr.k1 >= tr.k2) and tr.total_area == pytest.approx(1e4 * smp.total_area)
    assert tr.sigma == pytest.approx(100 * smp.sigma)
    assert np.array_equal(tr.u, smp.u) and tr.surface is smp.surface
    scan = hs.Torus().scan(300, seed=0).transformed(0.1, rot, shift)
    assert np.allclose(scan.viewpoints, 0.1 * hs.Torus().default_viewpoints() @ rot.T + shift)
    with pytest.raises(HeatcurvError, match="rotation"):
        smp.transformed(1.0, -np.eye(3))
    with pytest.raises(HeatcurvError):
        smp.transformed(0.0)
