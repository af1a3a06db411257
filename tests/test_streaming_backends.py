"""Large-cloud machinery: kNN neighbourhoods, spatial order, blocks, and the numba/numpy backends.

Every compiled kernel must give what its numpy twin gives: the two differ only
in the order floating-point terms are summed, so they agree to ~1e-15
relative; the tolerances below (1e-10 on sums, 1e-8 on eigenvectors and
fitted curvatures, which pass through solves with condition numbers up to
~1e4) leave room for that and nothing else.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import HeatcurvError, surfaces
from heatcurv.areas import density_areas, taper_sums
from heatcurv.backend import backend, get_backend, numba_available, set_backend, use_numba
from heatcurv.border import centroid_offset
from heatcurv.kernel import ball_taper, heat_kernel_weights, tapered_heat_weights
from heatcurv.mean_curvature import mean_curvature_normal
from heatcurv.neighbourhood import Neighbourhood, ball_neighbourhood, knn_neighbourhood
from heatcurv.normals import orient_normals, pca_normals
from heatcurv.scale import Scale, fit_at_scale, fit_blocks
from heatcurv.validation import prepare_points

needs_numba = pytest.mark.skipif(not numba_available(), reason="numba not installed")


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
        assert set(nb.indices[nb.indptr[i] : nb.indptr[i + 1]]) == set(ball.indices[ball.indptr[i] : ball.indptr[i + 1]])
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
        assert list(near.indices[near.indptr[i] : near.indptr[i + 1]]) == list(ref.indices[ref.indptr[i] : ref.indptr[i + 1]])
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


def test_backend_selection():
    assert get_backend() in ("auto", "numba", "numpy")
    with backend("numpy"):
        assert not use_numba()
    with pytest.raises(HeatcurvError, match="backend must be one of"):
        set_backend("fortran")


@needs_numba
def test_compiled_kernels_match_numpy(torus_cloud):
    pts, tree, nb = torus_cloud
    normals = surfaces.Torus().sample(6000, "random", seed=3).normals
    areas = density_areas(nb)
    h = nb.radius / 2
    results = {}
    for name in ("numpy", "numba"):
        with backend(name):
            results[name] = dict(
                taper=taper_sums(nb),
                fit_weights=tapered_heat_weights(nb, h, areas),
                pca=pca_normals(pts, nb, taper=True),
                pca_plain=pca_normals(pts, nb),
                K=mean_curvature_normal(pts, nb, None, areas, h),
                K_given=mean_curvature_normal(pts, nb, heat_kernel_weights(nb, h), areas, h),
                offset=centroid_offset(pts, nb, normals, taper=True),
                oriented=orient_normals(pts, normals * np.where(np.arange(6000) % 3 == 0, -1.0, 1.0)[:, None], nb),
                offset_centres=centroid_offset(pts, nb.rows_slice(10, 60), normals[10:60], centres=pts[10:60] + 0.01),
            )
    a, b = results["numpy"], results["numba"]
    np.testing.assert_allclose(b["taper"], a["taper"], rtol=1e-12)
    for key in ("pca", "pca_plain"):
        sign = np.sign(np.einsum("ij,ij->i", a[key][0], b[key][0]))
        np.testing.assert_allclose(b[key][0] * sign[:, None], a[key][0], atol=1e-8)
        np.testing.assert_allclose(b[key][1], a[key][1], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(
        a["fit_weights"], np.exp(-(nb.distances**2) / np.repeat(h, 40) ** 2) * ball_taper(nb) * areas[nb.indices], rtol=1e-13
    )
    assert np.array_equal(a["oriented"], b["oriented"])
    for key in ("K", "K_given", "offset", "offset_centres", "fit_weights"):
        np.testing.assert_allclose(b[key], a[key], rtol=1e-10, atol=1e-12 * np.abs(a[key]).max())
    # the taper used by the kernels is ball_taper's
    np.testing.assert_allclose(a["taper"], nb.segment_sum(ball_taper(nb)), rtol=1e-12)


@needs_numba
@pytest.mark.parametrize("noise", [0.0, 0.004])
def test_estimate_same_with_either_backend(noise):
    sample = surfaces.Sphere(radius=1.5).sample(4000, "random", seed=5)
    pts = sample.points + noise * np.random.default_rng(0).normal(size=sample.points.shape)
    with backend("numpy"):
        a = heatcurv.estimate(pts)
    with backend("numba"):
        b = heatcurv.estimate(pts)
    assert a.info["scale"]["fit"] == b.info["scale"]["fit"]
    for name in ("mean", "gaussian", "k1", "k2", "area", "spacing", "mean_curvature_normal"):
        ref = getattr(a, name)
        np.testing.assert_allclose(getattr(b, name), ref, rtol=1e-7, atol=1e-7 * np.abs(ref).max())
    np.testing.assert_allclose(b.normals, a.normals, atol=1e-8)
    assert np.array_equal(a.reliable, b.reliable) and np.array_equal(a.border, b.border)


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


def test_without_numba_the_numpy_path_runs():
    """A machine where numba does not import (e.g. a Python newer than numba's wheels)."""
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['numba'] = None\n"  # makes `import numba` raise ImportError
        "import numpy as np, heatcurv\n"
        "from heatcurv.backend import numba_available, use_numba\n"
        "assert not numba_available() and not use_numba()\n"
        "s = heatcurv.surfaces.Sphere(radius=2.0).sample(3000, 'random', seed=1)\n"
        "res = heatcurv.estimate(s.points)\n"
        "print(float(np.median(res.mean)), 'numba' in sys.modules and sys.modules['numba'] is not None)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    median_mean, loaded = out.stdout.split()
    assert float(median_mean) == pytest.approx(0.5, rel=1e-3) and loaded == "False"


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
        return csgraph.connected_components(csr_matrix((np.ones(sub.n_pairs), sub.indices, sub.indptr), shape=(n, n)))[0]

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


@needs_numba
def test_segment_numba_eigenvectors_against_lapack():
    """heatcurv._segment_numba.smallest_eigenvectors (3x3 Jacobi) against np.linalg.eigh.

    Random, near-planar (smallest eigenvalue 1e-12 of the largest), diagonal, zero and
    identity matrices: eigenvalues to 1e-12 of the largest, eigenvectors to 1e-10 wherever
    the smallest eigenvalue is separated (else any unit vector of its eigenspace is right).
    """
    from heatcurv._segment_numba import smallest_eigenvectors

    rng = np.random.default_rng(11)
    A = rng.normal(size=(2000, 3, 3))
    cov = A @ A.transpose(0, 2, 1)
    flat = np.diag([1.0, 0.5, 1e-12])
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    cov[:100] = rot @ flat @ rot.T
    cov[100] = np.diag([3.0, 1.0, 2.0])
    cov[101] = 0.0
    cov[102] = np.eye(3)
    vectors, values = smallest_eigenvectors(cov)
    ref_values, ref_vectors = np.linalg.eigh(cov)
    scale = np.maximum(np.abs(ref_values).max(axis=1, keepdims=True), 1e-300)
    np.testing.assert_allclose(values / scale, ref_values / scale, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(vectors, axis=1), 1.0, rtol=1e-14)
    separated = (ref_values[:, 1] - ref_values[:, 0]) > 1e-6 * scale[:, 0]
    assert separated[:101].all() and not separated[101:103].any()
    alignment = np.abs(np.einsum("ij,ij->i", vectors, ref_vectors[:, :, 0]))
    np.testing.assert_allclose(alignment[separated], 1.0, atol=1e-10)
    np.testing.assert_allclose(np.abs(vectors[100]), [0.0, 1.0, 0.0], atol=1e-15)
