"""heatcurv.orient.normals: PCA normals, their orientation (outward, or towards a viewpoint) and tangent frames."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.geometry.neighbourhood import ball_neighbourhood
from heatcurv.geometry.spacing import global_spacing
from heatcurv.operators.operator import build_operator
from heatcurv.orient.normals import orient_normals, orient_towards_viewpoint, pca_normals, tangent_frames
from heatcurv.surfaces.accuracy import direction_error_deg


def worst_angle_deg(normals, exact):
    """The largest angle between oriented unit normals and the exact ones, degrees (atan2: exact at small angles)."""
    sine = np.linalg.norm(np.cross(normals, exact), axis=1)
    return float(np.degrees(np.arctan2(sine, np.einsum("ij,ij->i", normals, exact)).max()))


def test_pca_normals_of_a_plane_are_exact():
    sample = surfaces.Plane().sample(900, "random", seed=1)
    nb = ball_neighbourhood(sample.points, 0.2)
    nrm, planarity = pca_normals(sample.points, nb)
    np.testing.assert_allclose(np.abs(nrm[:, 2]), 1.0, atol=1e-12)
    # a flat patch: spread in two directions, none across; the least planar are corner
    # neighbourhoods of a random sample (measured min 0.098, median 0.6)
    assert planarity.min() > 0.05 and np.median(planarity) > 0.4


def test_pca_planarity_flags_a_line():
    t = np.linspace(0, 1, 50)
    line = np.c_[t, 2 * t, np.zeros_like(t)]
    blob = np.random.default_rng(0).normal(size=(200, 3)) * 0.01 + 5
    pts = np.vstack([line, blob, surfaces.Plane().sample(400, "grid").points + [0, 0, 9]])
    nb = ball_neighbourhood(pts, 0.2)
    _, planarity = pca_normals(pts, nb)
    assert planarity[5:45].max() < 1e-9  # along the line the normal is undefined


def test_orientation_is_consistent_and_outward_on_closed_surfaces(torus_sample, records):
    pts = torus_sample.points
    nb = ball_neighbourhood(pts, 4 * global_spacing(pts))
    nrm, _ = pca_normals(pts, nb)
    rng = np.random.default_rng(3)
    scrambled = nrm * rng.choice([-1.0, 1.0], size=(len(pts), 1))
    oriented = orient_normals(pts, scrambled, nb)
    assert np.all(np.einsum("ij,ij->i", oriented, torus_sample.normals) > 0)  # every one outward
    records.check(
        "normals/torus-fibonacci-8000-pca", normal_deg=direction_error_deg(oriented, torus_sample.normals),
        normal_max_deg=worst_angle_deg(oriented, torus_sample.normals),
    )


def test_orientation_of_two_components_each_outward(records):
    a = surfaces.Sphere(radius=1.0).sample(1500, "fibonacci").points
    b = surfaces.Sphere(radius=0.5).sample(800, "fibonacci").points + [5.0, 0, 0]
    pts = np.vstack([a, b])
    res = heatcurv.estimate(pts)
    centre = np.where(np.arange(len(pts))[:, None] < 1500, 0.0, [5.0, 0, 0])
    assert np.all(np.einsum("ij,ij->i", res.normals, pts - centre) > 0)
    # different spacing on each sphere, global h: still 1/R (median)
    records.check(
        "normals/two-spheres-fibonacci-2300", median_mean_r1=100 * (np.median(res.mean[:1500]) - 1.0),
        median_mean_r05=100 * (np.median(res.mean[1500:]) / 2.0 - 1),
    )


def test_open_patch_orientation_is_consistent():
    # the saddle's outward vote is weak (nearly flat in the mean): every normal still agrees
    sample = surfaces.Saddle().sample(2500, "random", seed=2)
    res = heatcurv.estimate(sample.points)
    dots = np.einsum("ij,ij->i", res.normals, sample.normals)
    assert np.all(dots > 0) or np.all(dots < 0)


def test_viewpoint_orientation():
    pts = surfaces.Plane().sample(100, "grid").points
    nrm = np.tile([0.0, 0.0, 1.0], (100, 1)) * np.where(np.arange(100) % 2, 1.0, -1.0)[:, None]
    out = orient_towards_viewpoint(pts, nrm, (0.0, 0.0, -10.0))
    np.testing.assert_array_equal(out[:, 2], -1.0)


def test_tangent_frames_are_right_handed():
    n = np.random.default_rng(4).normal(size=(1000, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    n[0] = [0, 0, 1.0]
    n[1] = [1.0, 0, 0]
    e1, e2 = tangent_frames(n)
    np.testing.assert_allclose(np.einsum("ij,ij->i", e1, n), 0, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(e1, axis=1), 1, rtol=1e-14)
    np.testing.assert_allclose(np.cross(e1, e2), n, atol=1e-14)


def test_orientation_graph_neighbours_agree(torus_cloud):
    pts, tree, nb = torus_cloud
    sample = surfaces.Torus().sample(6000, "random", seed=3)
    scrambled = sample.normals * np.where(np.random.default_rng(2).random(6000) < 0.5, -1.0, 1.0)[:, None]
    for k in (None, 10, 6):
        oriented = orient_normals(pts, scrambled, nb, graph_neighbours=k)
        assert np.all(np.einsum("ij,ij->i", oriented, sample.normals) > 0.99)  # outward everywhere


def scan_lines_sphere(lines=40, anisotropy=16):
    """A unit sphere sampled along latitude lines, ``anisotropy`` times denser along them than across."""
    parts = []
    for lat in np.linspace(-1.4, 1.4, lines):
        m = int(lines * anisotropy * np.cos(lat))
        lon = np.linspace(0, 2 * np.pi, m, endpoint=False) + lat
        parts.append(np.c_[np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.full(m, np.sin(lat))])
    return np.vstack(parts)


def test_orientation_graph_spans_scan_lines(records):
    from scipy.sparse import csgraph, csr_matrix

    pts = scan_lines_sphere()
    nb = build_operator(pts).neighbourhood
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
    assert np.all(np.einsum("ij,ij->i", res.normals, pts) > 0)  # every one outward
    records.check(
        "normals/sphere-scan-lines-40x16", normal_max_deg=worst_angle_deg(res.normals, pts),
        mean_max=100 * np.abs(res.mean - 1.0).max(),
    )


@pytest.mark.parametrize("taper", [False, True])
def test_pca_normals_of_some_rows_are_those_rows_of_every_rows_normals(taper):
    from heatcurv.geometry.neighbourhood import knn_neighbourhood

    pts = surfaces.Torus().sample(3000, "random", seed=2).points
    nbhd = knn_neighbourhood(pts, 30)
    rows = np.random.default_rng(0).choice(3000, 200, replace=False)
    every = pca_normals(pts, nbhd, taper=taper, roundness=True)
    some = pca_normals(pts, nbhd, taper=taper, roundness=True, rows=rows)
    for a, b in zip(every, some):
        np.testing.assert_array_equal(a[rows], b)
    with pytest.raises(heatcurv.HeatcurvError, match="weights or rows"):
        pca_normals(pts, nbhd, np.ones(nbhd.n_pairs), rows=rows)
