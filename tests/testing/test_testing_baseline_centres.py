"""Tests of ``quadric_curvature(..., centres=)``: the fit evaluated at chosen points only.

The subset evaluation must give the full evaluation's values at those points
(same neighbours from the whole cloud, same fit, same side of the normal),
which is what lets ``benchmarks/accuracy.py`` run its fixed-k oracle at a few
thousand points of a million-point cloud.  Measured: bit-identical on the
noisy torus, saddle and sphere below (max difference 0.0).
"""

from __future__ import annotations

import numpy as np
import pytest

from heatcurv import surfaces as hs
from heatcurv.errors import HeatcurvError
from support.baseline import BLOCK_ROWS, QuadricResult, quadric_curvature

FIELDS = ("normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "area", "spacing", "reliable", "neighbours")


def assert_rows_equal(sub, full, rows):
    for name in FIELDS:
        a, b = getattr(sub, name), getattr(full, name)[rows]
        assert a.shape == b.shape, name
        if a.dtype == bool or a.dtype.kind == "i":
            assert np.array_equal(a, b), name
        else:
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12, err_msg=name)


@pytest.mark.parametrize(
    ("surface", "noise", "k"),
    [("torus", 0.0012, 120), ("saddle", 0.006, 240), ("sphere", 0.0, 40)],
)
def test_subset_equals_full_evaluation(surface, noise, k):
    smp = hs.get(surface).sample(8000, "random", noise=noise, seed=5)
    full = quadric_curvature(smp.points, k=k)
    rows = np.random.default_rng(1).choice(len(smp), 1500, replace=False)
    rows = np.concatenate([rows, rows[:7]])  # repeats and any order
    sub = quadric_curvature(smp.points, k=k, centres=rows)
    assert isinstance(sub, QuadricResult) and len(sub) == rows.size
    assert_rows_equal(sub, full, rows)
    assert np.array_equal(sub.info["centres"], rows) and full.info["centres"] is None
    assert sub.options.k == k


def test_wide_fit_shrinks_the_block_and_stays_equal():
    # k = 600: a block of 4096 points would hold 2.5M neighbour rows (~250 MB);
    # it is cut to BLOCK_ROWS // k = 1747 points (the full evaluation of 2400
    # points runs in 2 blocks); the values do not depend on it
    smp = hs.Sphere().sample(2400, "random", noise=0.006, seed=2)  # caps of a quarter sphere
    k = 600
    assert BLOCK_ROWS // k < len(smp) < 4096
    rows = np.random.default_rng(3).choice(len(smp), 600, replace=False)
    a = quadric_curvature(smp.points, k=k, centres=rows)
    b = quadric_curvature(smp.points, k=k, centres=rows, block=64)
    assert_rows_equal(a, b, np.arange(rows.size))
    full = quadric_curvature(smp.points, k=k)
    assert_rows_equal(a, full, rows)


def test_given_normals_and_duplicates():
    smp = hs.Torus().sample(5000, "random", noise=0.001, seed=4)
    pts = np.vstack([smp.points, smp.points[:30]])  # rows 5000.. duplicate rows 0..29
    nrm = np.vstack([smp.normals, smp.normals[:30]])
    few = np.array([3, 5010, 10, 4999, 17])
    # enough centres to orient the normals over their own graph
    many = np.concatenate([few, np.random.default_rng(0).choice(5000, 1000, replace=False)])
    for normals, rows in ((None, many), (nrm, few)):  # given normals set the side of any subset
        full = quadric_curvature(pts, k=60, normals=normals)
        sub = quadric_curvature(pts, k=60, normals=normals, centres=rows)
        assert_rows_equal(sub, full, rows)
    # a duplicated point shares its area with its copy, as in the full evaluation
    assert sub.area[1] == pytest.approx(full.area[10]) and sub.area[1] == pytest.approx(full.area[5010])


def test_bad_centres_are_refused():
    pts = hs.Sphere().sample(500, "fibonacci").points
    for bad, match in (
        ([0.5, 2], "integers"),
        (np.ones(500, dtype=bool), "integers"),
        ([[1, 2]], "1-D"),
        ([], "empty"),
        ([0, 500], r"\[0, 500\)"),
        ([-1], r"\[0, 500\)"),
    ):
        with pytest.raises(HeatcurvError, match=match):
            quadric_curvature(pts, centres=bad)
