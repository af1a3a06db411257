"""heatcurv on the simulated scenes of the real-scan test set: a CAD part with sharp edges, a LiDAR tile.

The scenes (:mod:`heatcurv.surfaces.scenes`) carry exact normals, areas and the
sign of the curvature on known convex and concave parts; the LiDAR tile's
orientation checks are in tests/test_orientation.py. The measured errors are
records (tests/records.json); the plain assertions are the claims of docs/scans.md and
exact facts.
"""

import numpy as np
import pytest

import heatcurv
from heatcurv import io, surfaces


@pytest.fixture(scope="module")
def cad():
    part = surfaces.cad_part(20000)
    return part, heatcurv.estimate(part.points)


def test_cad_part_is_outward_across_its_sharp_edges(cad):
    part, res = cad
    outward = np.einsum("ij,ij->i", res.normals, part.normals) > 0
    assert outward.all()  # measured: every point (docs/scans.md: "outward across every sharp edge")
    assert res.info["orientation"].ambiguous == 0 and res.outlier.sum() == 0


def test_cad_part_area_and_curvature_signs(cad, records):
    part, res = cad
    # a ball's width from every edge: the boss bends away from its outward normal, the hole towards it
    far = part.edge_distance > res.info["scale"].median_radius
    boss, hole = part.convex & far, part.concave & far
    assert boss.sum() > 500 and hole.sum() > 500
    assert np.all(res.mean[boss] > 0) and np.all(res.mean[hole] < 0)
    # and by how much: +1/12 and -1/8 per mm
    records.check(
        "real_scenes/cad-part-20000", area=100 * (res.area.sum() / part.area - 1),
        median_mean_boss=100 * (np.median(res.mean[boss]) * 12 - 1),
        median_mean_hole=100 * (np.median(res.mean[hole]) * -8 - 1),
    )


def test_cad_part_sharp_edges_are_found(cad, records):
    # the points near an edge are features, those of the smooth faces are not
    part, res = cad
    features = heatcurv.sharp_features(res)
    far = part.edge_distance > 2 * res.info["scale"].median_radius
    records.check(
        "real_scenes/cad-part-20000-features", missed=100 * (1 - features.mask[part.sharp].mean()),
        smooth_flagged=100 * features.mask[far].mean(),
    )


def test_lidar_tile_up_on_ground_roofs_and_walls_and_its_random_half_agrees():
    # docs/scans.md: "a LiDAR tile oriented up on 100 % of ground and roofs and 99.7 % of walls, and its random half
    # agreeing on all of them"; measured: ground 16,324 and roofs 1,883 every point, walls 955 of 958 (99.69 %);
    # the half agrees on every ground, roof and wall point (the crowns, volumetric, on 76 %)
    tile = surfaces.lidar_tile(20000, seed=0)
    res = heatcurv.estimate(tile.points, orient="up")
    half = np.flatnonzero(np.random.default_rng(0).random(len(tile.points)) < 0.5)
    part = heatcurv.estimate(tile.points[half], orient="up")
    same = np.einsum("ij,ij->i", res.normals[half], part.normals) > 0
    for label, wrong in ((surfaces.GROUND, 0), (surfaces.BUILDING_ROOF, 0), (surfaces.BUILDING_WALL, 3)):
        on = (tile.labels == label) & ~res.outlier
        assert on.sum() > 900
        assert (np.einsum("ij,ij->i", res.normals[on], tile.normals[on]) <= 0).sum() <= wrong, label
        assert same[on[half] & ~part.outlier].all(), label


def test_lidar_tile_survives_the_las_round_trip_and_noise(tmp_path, records):
    # the tile at twice the noise, stored in a LAZ file (1 cm integers): ground still faces the sky
    tile = surfaces.lidar_tile(10000, noise=0.06, seed=5)
    path = tmp_path / "tile.laz"
    io.write_points(path, tile.points)
    points = io.read_points(path).points
    res = heatcurv.estimate(points, orient="up")
    ground = tile.labels == 2
    records.check(
        "real_scenes/lidar-tile-10000-noise0.06-laz", wrong_side_ground=100 * (1 - (res.normals[ground, 2] > 0).mean()),
        wrong_sign_convex=100 * (1 - (res.mean[tile.convex & res.reliable] > 0).mean()),
    )


def test_what_one_smooth_surface_does_not_explain_is_unreliable(cad, records):
    # the fit's residual against the cloud's median: tree crowns (volumetric) and the band of a
    # ball's width along a CAD part's edges (where the ball holds two faces) are flagged; smooth
    # faces and noisy smooth surfaces are not
    part, res = cad
    far = part.edge_distance > 2 * res.info["scale"].median_radius
    records.check(
        "real_scenes/cad-part-20000-reliable", smooth_unreliable=100 * (1 - res.reliable[far].mean()),
        edges_reliable=100 * res.reliable[part.sharp].mean(),
    )
    tile = surfaces.lidar_tile(12000, seed=6)
    crowns = tile.labels == 5
    crowns_reliable = heatcurv.estimate(tile.points, orient="up").reliable[crowns].mean()
    records.check("real_scenes/lidar-tile-12000-up-crowns", reliable=100 * crowns_reliable)
    noisy = surfaces.Torus().sample(20000, "random", seed=0, noise=0.006)
    noisy_reliable = heatcurv.estimate(noisy.points).reliable.mean()
    records.check("real_scenes/torus-random-20000-noise0.006", unreliable=100 * (1 - noisy_reliable))
