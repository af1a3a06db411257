"""Tests of heatcurv.surfaces.patches: the folded square (angle, normals, fold distance).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from heatcurv import surfaces as hs


@pytest.mark.parametrize("angle", [30.0, 60.0, 90.0, 135.0, 180.0])
def test_folded_square_angle_and_fold_distance(angle):
    surf = hs.FoldedSquare(interior_angle=angle, size=1.0)
    # face normals from the clean geometry (three points on each face)
    left = surf.position([-0.9, -0.5, -0.9], [-0.5, 0.0, 0.5])
    right = surf.position([0.9, 0.5, 0.9], [-0.5, 0.0, 0.5])
    nl = np.cross(left[1] - left[0], left[2] - left[0])
    nr = np.cross(right[1] - right[0], right[2] - right[0])
    nl, nr = nl * np.sign(nl[2]), nr * np.sign(nr[2])  # both upward
    cos_n = nl @ nr / (np.linalg.norm(nl) * np.linalg.norm(nr))
    assert math.degrees(math.acos(np.clip(cos_n, -1, 1))) == pytest.approx(180 - angle, abs=1e-6)
    # interior angle between the faces, at the fold, measured inside the roof
    a = surf.position([0.7], [0.2])[0] - surf.position([0.0], [0.2])[0]
    b = surf.position([-0.4], [0.2])[0] - surf.position([0.0], [0.2])[0]
    cos_i = a @ b / (np.linalg.norm(a) * np.linalg.norm(b))
    assert math.degrees(math.acos(np.clip(cos_i, -1, 1))) == pytest.approx(angle, abs=1e-6)
    # analytic normals agree with the faces and point up; the fold is the ridge
    n = surf.normal([-0.5, 0.5, 0.0], [0.0, 0.0, 0.0])
    assert np.allclose(n[0], nl / np.linalg.norm(nl), atol=1e-14)
    assert np.allclose(n[1], nr / np.linalg.norm(nr), atol=1e-14)
    assert np.allclose(n[2], [0, 0, 1])  # bisector on the fold itself
    smp = surf.sample(2000, "random", seed=7)
    assert np.all(smp.clean_points[:, 2] <= 1e-15)  # fold at the top
    # distance to the fold line (the y axis), computed in 3-D ...
    p = smp.clean_points
    line = np.hypot(p[:, 0], p[:, 2])
    assert np.allclose(smp.feature_distance, line, rtol=1e-14, atol=1e-15)
    assert np.array_equal(smp.fold_distance, surf.fold_distance(smp.u, smp.v))
    # ... equals the distance along the surface (|u|, the flat square unfolded)
    assert np.allclose(smp.feature_distance, np.abs(smp.u), atol=1e-15)
    near = smp.near_feature(0.1)
    assert np.array_equal(near, line <= 0.1) and 0 < near.sum() < len(smp)
    assert np.all(smp.k1 == 0) and np.all(smp.mean == 0) and np.all(smp.umbilic)
    if angle == 180.0:
        assert np.allclose(smp.clean_points[:, 2], 0.0)
