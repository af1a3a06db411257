"""Tests of heatcurv.surfaces.rays: implicit functions, their Lipschitz bounds, and first hits of rays.
"""

from __future__ import annotations

import numpy as np
import pytest
from surfaces_helpers import CASES, random_params, residual, segment_signs

from heatcurv import surfaces as hs


@pytest.mark.parametrize("case", sorted(CASES))
def test_implicit_function(case):
    surf = CASES[case]()
    u, v = random_params(surf, n=300, seed=8)
    p, n = surf.position(u, v), surf.normal(u, v)
    assert np.max(np.abs(surf.implicit(p))) < 1e-12
    eps = 1e-4
    assert np.all(surf.implicit(p + eps * n) > 0) and np.all(surf.implicit(p - eps * n) < 0)
    # the Lipschitz constant the ray marcher relies on bounds the difference quotient
    lo, hi = surf.bounding_box()
    assert np.all(lo <= p.min(axis=0) + 1e-12) and np.all(p.max(axis=0) <= hi + 1e-12)
    rng = np.random.default_rng(1)
    q1 = rng.uniform(lo, hi, (5000, 3))
    q2 = q1 + rng.normal(0, 0.01, (5000, 3))
    ratio = np.abs(surf.implicit(q1) - surf.implicit(q2)) / np.linalg.norm(q1 - q2, axis=1)
    assert np.max(ratio) <= surf._implicit_lipschitz() * (1 + 1e-9)


def random_rays(surf, m, seed):
    """Origins at 3 bounding radii, aimed at random points of the bounding box."""
    rng = np.random.default_rng(seed)
    lo, hi = surf.bounding_box()
    centre, rb = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
    o = rng.normal(size=(m, 3))
    o = centre + 3 * rb * o / np.linalg.norm(o, axis=1)[:, None]
    d = rng.uniform(lo, hi, (m, 3)) - o
    return o, d / np.linalg.norm(d, axis=1)[:, None]


@pytest.mark.parametrize("case", sorted(CASES))
def test_ray_intersect_finds_the_first_hit(case):
    surf = CASES[case]()
    o, d = random_rays(surf, 400, seed=9)
    t = surf.ray_intersect(o, 2.5 * d)  # directions need not be unit
    assert t.shape == (400,)
    hit = np.isfinite(t)
    assert 0.2 < hit.mean() and np.all(t[hit] > 0)
    p = o[hit] + t[hit, None] * d[hit]
    # on the surface (independent implicit equation) and within its border
    scale = np.max(np.abs(p))
    assert np.max(np.abs(residual(case, surf, p, strict=False))) < 1e-10 * max(1, scale)
    # the inverse parametrisation recovers the hit
    assert np.max(np.abs(surf.position(*surf.parameters_of(p)) - p)) < 1e-10
    # nothing in front of the hit: the residual keeps one sign along the segment
    sg = segment_signs(case, surf, o[hit], p)
    assert np.all((sg >= 0).all(axis=1) | (sg <= 0).all(axis=1))
    # misses really miss (within the sampled resolution)
    far = o[~hit] + 10 * np.linalg.norm(o[0]) * d[~hit]
    sg = segment_signs(case, surf, o[~hit], far, end=1.0)
    assert np.all((sg >= 0).all(axis=1) | (sg <= 0).all(axis=1))


def test_ray_intersect_closed_forms_agree_with_the_marcher_and_torus_quartic():
    for surf in (hs.Sphere(radius=1.7, centre=(0.3, -0.2, 0.5)), hs.Ellipsoid(0.7, 1.3, 1.9)):
        o, d = random_rays(surf, 300, seed=10)
        closed = surf.ray_intersect(o, d)
        marched = hs.Surface._intersect(surf, o, d)  # the generic algorithm
        both = np.isfinite(closed) & np.isfinite(marched)
        assert np.array_equal(np.isfinite(closed), np.isfinite(marched))
        assert np.allclose(closed[both], marched[both], rtol=1e-12, atol=1e-12)
    # torus: smallest positive real root of the quartic, by numpy.roots
    torus = hs.Torus()
    o, d = random_rays(torus, 60, seed=11)
    t = torus.ray_intersect(o, d)
    r1, r2 = torus.r1, torus.r2
    for oi, di, ti in zip(o, d, t):
        # ((|o + t d|^2 + r2^2 - r1^2)^2 = 4 r2^2 ((o + t d)_x^2 + (o + t d)_y^2)
        P = np.polynomial.Polynomial
        q = P([oi @ oi + r2 * r2 - r1 * r1, 2 * oi @ di, 1.0])
        xy = P([oi[:2] @ oi[:2], 2 * oi[:2] @ di[:2], di[:2] @ di[:2]])
        roots = (q * q - 4 * r2 * r2 * xy).roots()
        real = roots.real[(np.abs(roots.imag) < 1e-9) & (roots.real > 0)]
        if real.size == 0:
            assert not np.isfinite(ti)
        else:
            assert ti == pytest.approx(real.min(), rel=1e-9)
