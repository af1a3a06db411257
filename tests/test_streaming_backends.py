"""Large-cloud machinery: kNN neighbourhoods, spatial order, blocks, threads.

(The compiled kernels against their numpy references: test_kernels_segment.py,
test_kernels_chordfit.py.)
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.areas import density_areas
from heatcurv.backend import threads
from heatcurv.neighbourhood import Neighbourhood, ball_neighbourhood, knn_neighbourhood
from heatcurv.normals import orient_normals
from heatcurv.scale import Scale, fit_at_scale, fit_blocks
from heatcurv.validation import prepare_points


@pytest.fixture(scope="module")
def torus_cloud():
    pts = surfaces.Torus().sample(6000, "random", seed=3).points
    tree = cKDTree(pts)
    return pts, tree, knn_neighbourhood(pts, 40, tree=tree)


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


def test_reordered_points_map_back_to_input_rows():
    rng = np.random.default_rng(1)
    pts = rng.random((500, 3))
    pts = np.vstack([pts, pts[:7]])  # duplicates
    prep = prepare_points(pts)
    order = rng.permutation(prep.n_distinct)
    moved = prep.reordered(order)
    np.testing.assert_array_equal(moved.points[moved.inverse] + moved.offset, pts)
    np.testing.assert_array_equal(moved.first, prep.first[order])
    area = rng.random(prep.n_distinct)
    assert moved.share_among_duplicates(area[order]).sum() == pytest.approx(area.sum(), rel=1e-12)


def test_fit_blocks_reuse_and_block_size_change_nothing(torus_cloud):
    pts, tree, _ = torus_cloud
    sample = surfaces.Torus().sample(6000, "random", seed=3)
    base = knn_neighbourhood(pts, 60, tree=tree)
    areas = density_areas(base)
    whole, h, nb, _ = fit_at_scale(pts, tree, sample.normals, areas, Scale(60, False))
    parts = list(fit_blocks(pts, tree, sample.normals, areas, Scale(60, False), base=base, block_pairs=50_000))
    assert len(parts) > 5
    k1 = np.concatenate([p[3].principal.k1 for p in parts])
    np.testing.assert_allclose(k1, whole.principal.k1, rtol=1e-12)
    np.testing.assert_allclose(h, base.radius / 2, rtol=1e-15)
    # coarse level for wide kernels: the pairs per centre stay at about k_fit
    *_, nbw, fraction = fit_at_scale(pts, tree, sample.normals[:100], areas, Scale(960, True), centres=np.arange(100))
    assert fraction == pytest.approx(0.25, rel=0.01) and np.all(nbw.counts <= 241)


def test_orientation_graph_neighbours_agree(torus_cloud):
    pts, tree, nb = torus_cloud
    sample = surfaces.Torus().sample(6000, "random", seed=3)
    scrambled = sample.normals * np.where(np.random.default_rng(2).random(6000) < 0.5, -1.0, 1.0)[:, None]
    for k in (None, 10, 6):
        oriented = orient_normals(pts, scrambled, nb, graph_neighbors=k)
        assert np.all(np.einsum("ij,ij->i", oriented, sample.normals) > 0.99)  # outward everywhere


def test_input_order_changes_nothing_with_spatial_reordering():
    sample = surfaces.Ellipsoid().sample(5000, "random", seed=4)
    perm = np.random.default_rng(0).permutation(5000)
    a = heatcurv.estimate(sample.points)
    b = heatcurv.estimate(sample.points[perm])
    for name in ("mean", "k1", "k2", "area"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name)[perm], rtol=1e-9, atol=1e-12)


def test_progress_reports_every_stage_and_threads_change_nothing():
    sample = surfaces.Sphere().sample(3000, "random", seed=2)
    calls = []
    res = heatcurv.estimate(sample.points, progress=lambda stage, fraction: calls.append((stage, fraction)))
    stages = [s for s, f in calls if f == 0.0]
    assert stages == ["validate", "neighbours", "spacing", "areas", "normals", "orientation", "mean", "principal"]
    assert all(0.0 <= f <= 1.0 for _, f in calls) and calls[-1] == ("principal", 1.0)
    assert set(res.info["timings"]) == set(stages)
    single = heatcurv.estimate(sample.points, workers=1)
    np.testing.assert_allclose(single.mean, res.mean, rtol=1e-12)


def scan_lines_sphere(lines=40, anisotropy=16):
    """A unit sphere sampled along latitude lines, ``anisotropy`` times denser along them than across."""
    parts = []
    for lat in np.linspace(-1.4, 1.4, lines):
        m = int(lines * anisotropy * np.cos(lat))
        lon = np.linspace(0, 2 * np.pi, m, endpoint=False) + lat
        parts.append(np.c_[np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.full(m, np.sin(lat))])
    return np.vstack(parts)


def test_orientation_graph_spans_scan_lines():
    from scipy.sparse import csgraph, csr_matrix

    pts = scan_lines_sphere()
    nb = heatcurv.build_operator(pts).neighbourhood
    n = nb.n_points

    def components(sub):
        graph = csr_matrix((np.ones(sub.n_pairs), sub.indices, sub.indptr), shape=(n, n))
        return csgraph.connected_components(graph)[0]

    assert components(nb.nearest(10)) == 40  # the nearest ten: one component per scan line
    spread = nb.spread(10)
    assert components(spread) == 1 and np.all(spread.counts == 10)
    ranks = np.searchsorted(nb.distances[:60], spread.distances[:10])
    assert list(ranks[:5]) == [0, 1, 2, 3, 4] and ranks[-1] == 59  # nearest half, then out to the edge
    res = heatcurv.estimate(pts)
    assert np.all(np.einsum("ij,ij->i", res.normals, pts) > 0.99)
    np.testing.assert_allclose(res.mean, 1.0, atol=0.02)


def test_concurrent_calls_from_threads_agree():
    """Dask-style use: several estimates at once in one process (numba's thread pool is shared)."""
    from concurrent.futures import ThreadPoolExecutor

    sample = surfaces.Sphere(radius=2.0).sample(3000, "random", seed=6)
    alone = heatcurv.estimate(sample.points)
    with ThreadPoolExecutor(3) as pool:
        results = list(pool.map(lambda _: heatcurv.estimate(sample.points), range(3)))
    for res in results:
        np.testing.assert_array_equal(res.mean, alone.mean)
        np.testing.assert_array_equal(res.normals, alone.normals)


def test_threads_sets_numba_threads_for_this_thread_only():
    """numba's thread count is thread-local: threads(1) limits this thread's kernels, not another thread's."""
    import threading

    import numba

    default = numba.get_num_threads()
    seen = {}
    with threads(1):
        assert numba.get_num_threads() == 1
        other = threading.Thread(target=lambda: seen.setdefault("other", numba.get_num_threads()))
        other.start()
        other.join()
    assert numba.get_num_threads() == default and seen["other"] == default
    with threads(None), threads(-1):
        assert numba.get_num_threads() == default
