"""heatcurv.geometry.neighbourhood: ball neighbourhoods in CSR form, their segment sums and row blocks."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.geometry.neighbourhood import Neighbourhood, ball_neighbourhood, knn_neighbourhood


def grid(m=21, step=0.1):
    x, y = np.meshgrid(np.arange(m) * step, np.arange(m) * step)
    return np.c_[x.ravel(), y.ravel(), np.zeros(m * m)]


def test_ball_neighbourhood_matches_brute_force():
    pts = np.random.default_rng(2).random((400, 3))
    r = 0.15
    nb = ball_neighbourhood(pts, r, min_neighbours=3)
    d = cdist(pts, pts)
    for i in (0, 17, 399):
        expect = np.flatnonzero((d[i] <= r) & (np.arange(400) != i))
        got = nb.indices[nb.indptr[i] : nb.indptr[i + 1]]
        if not nb.augmented[i]:
            np.testing.assert_array_equal(got, expect)
    rows = nb.rows
    np.testing.assert_allclose(nb.distances, d[rows, nb.indices], rtol=1e-12)
    assert not np.any(rows == nb.indices)  # the point itself is not stored
    full = ~nb.augmented
    # symmetric for a scalar radius: j in B(i) <=> i in B(j) (among non-augmented points)
    pairs = set(zip(rows[full[rows] & full[nb.indices]].tolist(), nb.indices[full[rows] & full[nb.indices]].tolist()))
    assert all((j, i) in pairs for i, j in pairs)


def test_isolated_points_get_their_nearest_neighbours():
    pts = np.vstack([grid(11, 0.1), [[5.0, 5.0, 1.0]]])
    nb = ball_neighbourhood(pts, 0.15, min_neighbours=6)
    assert nb.augmented[-1] and nb.counts[-1] == 6
    # interior grid points have 8 neighbours within 0.15 and are left alone; corners (3) are augmented
    assert not nb.augmented[12] and nb.counts[12] == 8
    assert nb.augmented[0] and nb.counts[0] == 6
    far = nb.indices[nb.indptr[-2] : nb.indptr[-1]]
    d = np.linalg.norm(pts[:-1] - pts[-1], axis=1)
    np.testing.assert_array_equal(np.sort(far), np.sort(np.argsort(d)[:6]))


def test_ball_queries_in_blocks_change_nothing(monkeypatch):
    import heatcurv.geometry.neighbourhood as neighbourhood_module

    # a random cube with a far point: augmented rows in some blocks, counts that vary by block
    pts = np.vstack([np.random.default_rng(4).random((2000, 3)), [[3.0, 3.0, 3.0]]])
    whole = ball_neighbourhood(pts, 0.08, min_neighbours=6)
    assert whole.augmented.sum() > 10
    monkeypatch.setattr(neighbourhood_module, "BLOCK_PAIRS", 500)  # blocks of about 8 to 60 queries
    blocked = ball_neighbourhood(pts, 0.08, min_neighbours=6)
    for name in ("indptr", "indices", "distances", "radius", "augmented"):
        np.testing.assert_array_equal(getattr(blocked, name), getattr(whole, name))
    assert blocked.indices.dtype == whole.indices.dtype == np.int32


def test_segment_sum_and_counts():
    pts = np.random.default_rng(3).random((100, 3))
    nb = ball_neighbourhood(pts, 0.3, min_neighbours=3)
    ones = nb.segment_sum(np.ones(nb.n_pairs))
    np.testing.assert_array_equal(ones, nb.counts)
    assert nb.n_points == 100 and nb.indptr[-1] == nb.n_pairs


def test_ball_holds_the_expected_number_of_points_on_a_sphere():
    # a ball of chord radius r cuts a cap of area exactly pi r^2 from a unit sphere, so
    # each of the n - 1 other points of an area-uniform random sample lies in it with
    # probability r^2 / 4
    n = 4000
    pts = surfaces.Sphere().sample(n, "random", seed=5).points
    r = 0.2
    nb = ball_neighbourhood(pts, r)
    # the mean of 4000 correlated counts of ~40: relative std well below 1 %
    assert nb.counts.mean() == pytest.approx((n - 1) * r**2 / 4, rel=0.01)


def test_fitting_in_blocks_changes_nothing(monkeypatch):
    import heatcurv.geometry.neighbourhood as neighbourhood_module

    sample = surfaces.Torus().sample(3000, "random", seed=6)
    whole = heatcurv.estimate(sample.points)
    monkeypatch.setattr(neighbourhood_module, "BLOCK_PAIRS", 5000)  # the one block-size policy: about 80 blocks
    blocked = heatcurv.estimate(sample.points)
    for name in whole.FIELDS:
        np.testing.assert_allclose(getattr(blocked, name), getattr(whole, name), rtol=1e-12, atol=1e-12)


def test_row_blocks_cover_every_row_once():
    pts = np.random.default_rng(7).random((500, 3))
    nb = ball_neighbourhood(pts, 0.2, min_neighbours=3)
    blocks = list(nb.row_blocks(300))
    assert blocks[0][0] == 0 and blocks[-1][1] == 500
    assert all(b[1] == c[0] for b, c in zip(blocks, blocks[1:]))
    sub = nb.rows_slice(*blocks[1])
    np.testing.assert_array_equal(sub.counts, nb.counts[blocks[1][0] : blocks[1][1]])


def test_knn_neighbourhood_is_the_ball_of_radius_dk(torus_cloud):
    pts, tree, nb = torus_cloud
    # random points: no ties at the radius, so the same sets row by row (the ball query
    # rounds its own distances: a hair wider keeps the k-th neighbour itself)
    ball = ball_neighbourhood(pts, nb.radius * (1 + 1e-12), tree=tree)
    assert np.array_equal(nb.counts, ball.counts)
    assert np.all(nb.counts == 40)
    for i in (0, 123, 5999):
        row, ball_row = slice(nb.indptr[i], nb.indptr[i + 1]), slice(ball.indptr[i], ball.indptr[i + 1])
        assert set(nb.indices[row]) == set(ball.indices[ball_row])
    d = nb.distances.reshape(-1, 40)
    assert np.all(np.diff(d, axis=1) >= 0) and np.array_equal(nb.radius, d[:, -1])
    np.testing.assert_allclose(d, np.linalg.norm(pts[nb.indices].reshape(-1, 40, 3) - pts[:, None], axis=2), rtol=1e-14)
    assert nb.indices.dtype == np.int32 and not nb.augmented.any()


def test_knn_neighbourhood_blocks_outside_queries_and_levels(torus_cloud):
    pts, tree, nb = torus_cloud
    small = knn_neighbourhood(pts, 40, tree=tree, block=777)
    assert np.array_equal(small.indices, nb.indices) and np.array_equal(small.distances, nb.distances)
    # queries that are not cloud points keep all k neighbours
    q = pts[:5] + 1e-3
    off = knn_neighbourhood(pts, 7, tree=tree, queries=q)
    d, i = tree.query(q, k=7)
    assert np.array_equal(off.indices.reshape(-1, 7), i) and np.allclose(off.distances.reshape(-1, 7), d)
    # a coarse level: indices are mapped to the whole cloud
    level = np.arange(0, pts.shape[0], 3)
    sub = knn_neighbourhood(pts[level], 10, queries=pts[:50], source_index=level)
    assert np.all(np.isin(sub.indices, level))
    assert np.all(sub.indices.reshape(-1, 10)[::3] != np.arange(50)[::3, None])  # members skip themselves
    with pytest.raises(HeatcurvError, match="need more than"):
        knn_neighbourhood(pts[:5], 5)


def test_nearest_concatenate_blockwise():
    rng = np.random.default_rng(0)
    pts = rng.random((300, 3))
    ball = ball_neighbourhood(pts, 0.2)  # rows sorted by index, not distance
    near = ball.nearest(5)
    ref = knn_neighbourhood(pts, 5)
    full = ball.counts >= 5
    rows = np.flatnonzero(full)[:20]
    for i in rows:
        near_row, ref_row = slice(near.indptr[i], near.indptr[i + 1]), slice(ref.indptr[i], ref.indptr[i + 1])
        assert list(near.indices[near_row]) == list(ref.indices[ref_row])
    np.testing.assert_allclose(near.radius[full], ref.radius[full])
    assert np.array_equal(ref.nearest(3).indices, ref.indices.reshape(-1, 5)[:, :3].ravel())
    parts = [ball.rows_slice(lo, hi) for lo, hi in ball.row_blocks(500)]
    assert len(parts) > 1
    joined = Neighbourhood.concatenate(parts)
    for name in ("indptr", "indices", "distances", "radius", "augmented"):
        assert np.array_equal(getattr(joined, name), getattr(ball, name))
    sums = ball.blockwise(lambda lo, hi, b: b.segment_sum(b.distances), max_pairs=300)
    np.testing.assert_allclose(sums, ball.segment_sum(ball.distances), rtol=1e-14)
