"""heatcurv.surfaces.scenes: the LiDAR tile and the CAD part against independent checks.

The terrain's curvature is checked by finite differences of its height, the
part's area and normals by the divergence theorem and a solid written out
here, its edge distances by the closed-form distances to segments and circles.
"""

import math

import numpy as np
import pytest
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from heatcurv import surfaces as hs
from heatcurv.errors import HeatcurvError
from heatcurv.surfaces import scenes

ORIGIN = np.array([500000.0, 5000000.0, 200.0])


@pytest.fixture(scope="module")
def tile():
    return hs.lidar_tile()


@pytest.fixture(scope="module")
def clean_tile():
    return hs.lidar_tile(8000, noise=0.0, quantum=0.0, seed=4)


@pytest.fixture(scope="module")
def part():
    return hs.cad_part()


def unit_rows(a):
    return np.abs(np.linalg.norm(a, axis=1) - 1.0)


# --------------------------------------------------------------------------- both scenes


@pytest.mark.parametrize("make", [hs.lidar_tile, hs.cad_part], ids=["lidar_tile", "cad_part"])
def test_same_seed_same_scene_other_seed_other_points(make):
    a, b, c = make(3000, seed=7), make(3000, seed=7), make(3000, seed=8)
    for name in ("points", "clean_points", "labels", "normals", "mean", "edge_distance", "sharp", "convex"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert not np.array_equal(a.clean_points, c.clean_points)


@pytest.mark.parametrize("make", [hs.lidar_tile, hs.cad_part], ids=["lidar_tile", "cad_part"])
@pytest.mark.parametrize("n", [4, 997, 20000])
def test_exactly_n_points_and_every_label_named(make, n):
    scene = make(n)
    assert len(scene) == scene.n == n
    for name in ("points", "clean_points", "normals"):
        assert getattr(scene, name).shape == (n, 3), name
    for name in ("labels", "mean", "gaussian", "edge_distance", "border_distance", "sharp", "convex", "concave"):
        assert getattr(scene, name).shape == (n,), name
    assert set(np.unique(scene.labels)) <= set(scene.classes)
    if n == 20000:
        assert set(np.unique(scene.labels)) == set(scene.classes)


@pytest.mark.parametrize("make", [hs.lidar_tile, hs.cad_part], ids=["lidar_tile", "cad_part"])
def test_curvature_undefined_exactly_at_sharp_points_and_in_vegetation(make):
    scene = make(5000)
    surface = scene.labels != hs.VEGETATION
    np.testing.assert_array_equal(np.isnan(scene.mean), scene.sharp | ~surface)
    np.testing.assert_array_equal(np.isnan(scene.gaussian), scene.sharp | ~surface)
    np.testing.assert_array_equal(scene.sharp, scene.edge_distance <= scene.margin)
    np.testing.assert_array_equal(scene.near_edge(scene.margin), scene.sharp)
    assert not np.any((scene.convex | scene.concave) & scene.sharp)
    assert scene.up_normals is scene.normals


@pytest.mark.parametrize("make", [hs.lidar_tile, hs.cad_part], ids=["lidar_tile", "cad_part"])
@pytest.mark.parametrize("bad", [{"noise": -0.1}, {"margin": -1.0}, {"noise": math.nan}])
def test_bad_arguments_raise(make, bad):
    with pytest.raises(HeatcurvError):
        make(1000, **bad)


def test_bad_n_quantum_origin_raise():
    with pytest.raises(HeatcurvError):
        hs.lidar_tile(3)
    with pytest.raises(HeatcurvError):
        hs.lidar_tile(1000, quantum=-0.01)
    with pytest.raises(HeatcurvError):
        hs.lidar_tile(1000, origin=(1.0, 2.0))


def test_allocation_is_proportional_and_exact():
    counts = scenes._allocate(10, [1.0, 1.0, 1.0])
    assert counts.sum() == 10 and sorted(counts) == [3, 3, 4]
    np.testing.assert_array_equal(scenes._allocate(100, [3.0, 1.0]), [75, 25])


# --------------------------------------------------------------------------- the LiDAR tile


def test_tile_is_60_m_square_at_utm_like_coordinates(tile):
    local = tile.clean_points - ORIGIN
    assert np.all(np.abs(local[:, :2]) <= 30.0 + 1e-9)
    assert np.all(np.abs(local[:, 2]) < 30.0)
    assert tile.extra["origin"] == tuple(ORIGIN)
    assert math.isnan(tile.area)


def test_points_are_quantised_and_noisy_as_asked(tile):
    q = tile.points / 0.01
    np.testing.assert_allclose(q, np.round(q), rtol=0, atol=1e-6)
    raw = hs.lidar_tile(noise=0.03, quantum=0.0)
    np.testing.assert_array_equal(raw.clean_points, tile.clean_points)
    assert np.std(raw.points - raw.clean_points) == pytest.approx(0.03, rel=0.03)
    # quantisation moves each coordinate by at most half a centimetre
    assert np.max(np.abs(tile.points - raw.points)) <= 0.005 + 1e-9
    exact = hs.lidar_tile(2000, noise=0.0, quantum=0.0)
    np.testing.assert_array_equal(exact.points, exact.clean_points)


def test_class_mix_like_an_aerial_scan(tile):
    share = {name: float(np.mean(tile.labels == code)) for code, name in tile.classes.items()}
    assert share["ground"] > 0.7
    assert 0.05 < share["building roof"] < 0.15
    assert 0.02 < share["building wall"] < share["building roof"]
    assert 0.02 < share["high vegetation"] < 0.1
    assert tile.classes[2] == "ground" and tile.classes[5] == "high vegetation" and tile.classes[6] == "building roof"
    assert (hs.GROUND, hs.VEGETATION, hs.BUILDING_ROOF, hs.BUILDING_WALL) == (2, 5, 6, 66)


def test_ground_and_roof_density_per_plan_area_and_walls_sparser(clean_tile):
    s = clean_tile
    local = s.clean_points - ORIGIN
    ground = s.labels == hs.GROUND
    # open ground far from everything: density per m^2 of plan
    box = ground & (np.abs(local[:, 0] + 20) < 5) & (np.abs(local[:, 1] - 25) < 4)
    rho_ground = box.sum() / 80.0
    roof = local[s.labels == hs.BUILDING_ROOF]
    flat = roof[np.abs(roof[:, 0] - 12) < 7]  # the flat-roofed building at (12, 12), 14 m x 10 m
    flat = flat[np.abs(flat[:, 1] - 12) < 5]
    assert flat.shape[0] / 140.0 == pytest.approx(rho_ground, rel=0.2)
    # a long wall of that building: y = 17, x in [5, 19]
    wall = local[(s.labels == hs.BUILDING_WALL) & (np.abs(local[:, 1] - 17) < 1e-9)]
    height = wall[:, 2].max() - wall[:, 2].min()
    rho_wall = wall.shape[0] / (14.0 * height)
    assert rho_wall / rho_ground == pytest.approx(0.2, rel=0.35)


def test_normals_unit_up_on_ground_and_roofs_horizontal_on_walls_nan_in_trees(tile):
    veg = tile.labels == hs.VEGETATION
    assert np.all(np.isnan(tile.normals[veg]))
    assert np.max(unit_rows(tile.normals[~veg])) < 1e-12
    up = (tile.labels == hs.GROUND) | (tile.labels == hs.BUILDING_ROOF)
    assert np.all(tile.normals[up, 2] > 0)
    walls = tile.labels == hs.BUILDING_WALL
    assert np.all(tile.normals[walls, 2] == 0.0)
    roofs = tile.labels == hs.BUILDING_ROOF
    tilted = roofs & (tile.normals[:, 2] < 1 - 1e-9)
    # the gable roof: pitch atan(3 / 5), the only tilted roof
    np.testing.assert_allclose(tile.normals[tilted, 2], math.cos(math.atan2(3.0, 5.0)), rtol=1e-12)


def test_wall_normals_point_out_of_their_building(tile):
    roofs = tile.clean_points[tile.labels == hs.BUILDING_ROOF]
    pairs = cKDTree(roofs[:, :2]).query_pairs(1.5, output_type="ndarray")
    n = roofs.shape[0]
    from scipy.sparse import coo_matrix

    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    k, label = connected_components(graph, directed=False)
    assert k == 3  # three buildings
    centres = np.array([roofs[label == i, :2].mean(axis=0) for i in range(k)])
    walls = tile.labels == hs.BUILDING_WALL
    p, nrm = tile.clean_points[walls, :2], tile.normals[walls, :2]
    owner = label[cKDTree(roofs[:, :2]).query(p)[1]]
    assert np.all(np.einsum("ij,ij->i", p - centres[owner], nrm) > 0)


def test_ground_lies_on_the_terrain_and_walls_stand_on_it(clean_tile):
    s = clean_tile
    ground = s.labels == hs.GROUND
    x, y, z = s.clean_points[ground].T
    np.testing.assert_allclose(z, hs.lidar_terrain(x, y), rtol=0, atol=1e-9)
    walls = s.clean_points[s.labels == hs.BUILDING_WALL]
    assert np.all(walls[:, 2] >= hs.lidar_terrain(walls[:, 0], walls[:, 1]) - 1e-9)
    local = hs.lidar_terrain(ORIGIN[0] + 1.0, ORIGIN[1] + 2.0, origin=(ORIGIN[0], ORIGIN[1], 0.0))
    assert float(local) == pytest.approx(hs.lidar_terrain(ORIGIN[0] + 1.0, ORIGIN[1] + 2.0) - 200.0)


def test_terrain_curvature_and_normals_match_finite_differences(clean_tile):
    s = clean_tile
    ok = (s.labels == hs.GROUND) & ~s.sharp
    x, y, _ = s.clean_points[ok].T
    h = 1e-3

    def f(dx, dy):
        return hs.lidar_terrain(x + dx, y + dy)

    fx = (f(h, 0) - f(-h, 0)) / (2 * h)
    fy = (f(0, h) - f(0, -h)) / (2 * h)
    fxx = (f(h, 0) - 2 * f(0, 0) + f(-h, 0)) / h**2
    fyy = (f(0, h) - 2 * f(0, 0) + f(0, -h)) / h**2
    fxy = (f(h, h) - f(h, -h) - f(-h, h) + f(-h, -h)) / (4 * h * h)
    w = np.sqrt(1 + fx**2 + fy**2)
    # graph with the upward normal: positive where the ground bends away from it (a hill top)
    mean = -((1 + fy**2) * fxx - 2 * fx * fy * fxy + (1 + fx**2) * fyy) / (2 * w**3)
    gauss = (fxx * fyy - fxy**2) / w**4
    np.testing.assert_allclose(s.mean[ok], mean, rtol=0, atol=2e-5)
    np.testing.assert_allclose(s.gaussian[ok], gauss, rtol=0, atol=2e-5)
    normal = np.column_stack([-fx, -fy, np.ones_like(fx)]) / w[:, None]
    np.testing.assert_allclose(s.normals[ok], normal, rtol=0, atol=1e-6)
    assert np.max(np.abs(s.mean[ok])) > 0.05  # the hill and the valley are really curved


def test_hill_is_convex_valley_concave_with_up_normals(tile):
    assert tile.convex.sum() > 200 and tile.concave.sum() > 150
    assert np.all(tile.labels[tile.convex | tile.concave] == hs.GROUND)
    assert np.all(tile.mean[tile.convex] > 0.03)
    assert np.all(tile.mean[tile.concave] < -0.03)
    # the hill's top: mean = height / sigma^2 = 3 / 36 up to the tilt
    top = np.argmin(np.linalg.norm(tile.clean_points[:, :2] - ORIGIN[:2] - [-14.0, 12.0], axis=1))
    assert tile.mean[top] == pytest.approx(3.0 / 36.0, rel=0.02)


def test_planes_have_zero_curvature_and_vegetation_none(tile):
    planar = np.isin(tile.labels, [hs.BUILDING_ROOF, hs.BUILDING_WALL]) & ~tile.sharp
    assert np.all(tile.mean[planar] == 0.0) and np.all(tile.gaussian[planar] == 0.0)
    veg = tile.labels == hs.VEGETATION
    assert np.all(np.isnan(tile.mean[veg])) and np.all(np.isinf(tile.edge_distance[veg]))
    assert not np.any(tile.sharp[veg])


def test_tile_sharp_points_sit_at_ridges_eaves_corners_and_feet(tile):
    assert 0.02 < tile.sharp.mean() < 0.1
    walls, roofs = tile.labels == hs.BUILDING_WALL, tile.labels == hs.BUILDING_ROOF
    assert min(tile.sharp[walls].mean(), tile.sharp[roofs].mean()) > 4 * tile.sharp[tile.labels == hs.GROUND].mean()
    # the ridge of the gable roof: its highest points are all sharp
    gable = roofs & (tile.normals[:, 2] < 1.0 - 1e-9)
    roof_z = np.where(gable, tile.clean_points[:, 2], -np.inf)
    assert np.all(tile.sharp[np.argsort(roof_z)[-20:]])
    # ground points right at a wall's foot
    ground = np.flatnonzero(tile.labels == hs.GROUND)
    wall_xy = cKDTree(tile.clean_points[walls, :2])
    close = ground[wall_xy.query(tile.clean_points[ground, :2])[0] < 0.2]
    assert close.size > 0 and np.all(tile.sharp[close])


def test_border_distance_is_the_ground_distance_to_the_tile_edge(tile):
    ground = tile.labels == hs.GROUND
    local = tile.clean_points[ground, :2] - ORIGIN[:2]
    np.testing.assert_allclose(tile.border_distance[ground], 30.0 - np.max(np.abs(local), axis=1), atol=1e-9)
    assert np.all(np.isinf(tile.border_distance[~ground]))


# --------------------------------------------------------------------------- the CAD part

RB, RH = 6.0, 4.0
BOSS, HOLE = np.array([-8.0, 0.0]), np.array([9.0, 0.0])


def inside_solid(p):
    """The part written out again: block minus the hole, plus the boss."""
    x, y, z = p.T
    block = (np.abs(x) < 20) & (np.abs(y) < 15) & (z > 0) & (z < 10)
    hole = np.hypot(x - HOLE[0], y - HOLE[1]) < RH
    boss = (np.hypot(x - BOSS[0], y - BOSS[1]) < RB) & (z >= 10) & (z < 18)
    return (block & ~hole) | boss


def test_part_area_is_exact():
    block = 2 * 40 * 30 + 2 * (40 + 30) * 10
    expected = block - 2 * math.pi * RH**2 + 2 * math.pi * RB * 8 + 2 * math.pi * RH * 10
    assert hs.cad_part_area() == pytest.approx(expected, rel=1e-14)
    assert hs.cad_part(100).area == hs.cad_part_area()


def test_part_volume_by_the_divergence_theorem_checks_area_normals_uniformity(part):
    # uniform by area with outward normals: (A / n) sum(x . n) / 3 -> volume, (A / n) sum(n) -> 0
    w = part.area / len(part)
    volume = 40 * 30 * 10 - math.pi * RH**2 * 10 + math.pi * RB**2 * 8
    assert w * np.einsum("ij,ij->", part.clean_points, part.normals) / 3 == pytest.approx(volume, rel=0.01)
    assert np.linalg.norm(w * part.normals.sum(axis=0)) < 0.02 * part.area


def test_part_points_split_over_the_faces_by_area(part):
    areas = {hs.BOSS_SIDE: 2 * math.pi * RB * 8, hs.HOLE_WALL: 2 * math.pi * RH * 10}
    areas[hs.PLANAR_FACE] = part.area - sum(areas.values())
    for label, area in areas.items():
        assert np.sum(part.labels == label) == pytest.approx(len(part) * area / part.area, abs=1.0)
    # inside one face: uniform (the bottom face's two halves about x = 0: equal areas)
    bottom = (part.clean_points[:, 2] == 0.0) & (part.labels == hs.PLANAR_FACE)
    left = np.sum(bottom & (part.clean_points[:, 0] < 0))
    right = np.sum(bottom & (part.clean_points[:, 0] > 0))
    ratio = (20 * 30) / (20 * 30 - math.pi * RH**2)
    assert left / right == pytest.approx(ratio, rel=0.08)


def test_part_normals_unit_and_outward(part):
    assert np.max(unit_rows(part.normals)) < 1e-12
    smooth = ~part.sharp
    p, n = part.clean_points[smooth], part.normals[smooth]
    eps = 1e-3
    assert not np.any(inside_solid(p + eps * n))
    assert np.all(inside_solid(p - eps * n))


def test_part_curvature_by_face(part):
    boss = (part.labels == hs.BOSS_SIDE) & ~part.sharp
    hole = (part.labels == hs.HOLE_WALL) & ~part.sharp
    planar = (part.labels == hs.PLANAR_FACE) & ~part.sharp
    np.testing.assert_allclose(part.mean[boss], 1 / (2 * RB), rtol=1e-15)
    np.testing.assert_allclose(part.mean[hole], -1 / (2 * RH), rtol=1e-15)
    assert np.all(part.mean[planar] == 0.0)
    assert np.all(part.gaussian[~part.sharp] == 0.0)
    np.testing.assert_array_equal(part.convex, boss)
    np.testing.assert_array_equal(part.concave, hole)
    # boss side points lie on their cylinder, hole wall points on theirs
    for mask, c, r in ((part.labels == hs.BOSS_SIDE, BOSS, RB), (part.labels == hs.HOLE_WALL, HOLE, RH)):
        np.testing.assert_allclose(np.linalg.norm(part.clean_points[mask, :2] - c, axis=1), r, rtol=1e-12)


def exact_edge_distance(p):
    """Distance to the part's 12 block edges and 4 circles, in closed form."""
    a, b, h = 20.0, 15.0, 10.0
    corners = np.array([[-a, -b], [a, -b], [a, b], [-a, b]])
    segments = []
    for z in (0.0, h):
        segments += [(np.r_[corners[i], z], np.r_[corners[(i + 1) % 4], z]) for i in range(4)]
    segments += [(np.r_[c, 0.0], np.r_[c, h]) for c in corners]
    best = np.full(p.shape[0], np.inf)
    for s0, s1 in segments:
        d = s1 - s0
        t = np.clip((p - s0) @ d / (d @ d), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(p - (s0 + t[:, None] * d), axis=1))
    for c, r, z in ((HOLE, RH, 0.0), (HOLE, RH, h), (BOSS, RB, h), (BOSS, RB, h + 8)):
        rho = np.linalg.norm(p[:, :2] - c, axis=1)
        best = np.minimum(best, np.hypot(rho - r, p[:, 2] - z))
    return best


def test_part_edge_distance_is_a_tight_lower_bound(part):
    exact = exact_edge_distance(part.clean_points)
    est = part.edge_distance
    assert np.all(est <= exact + 1e-9)
    near = exact <= 0.05 * 40
    assert np.max(exact[near] - est[near]) <= 1.5e-4 * 40
    assert np.max(exact - est) <= 2.5e-3 * 40
    np.testing.assert_array_equal(part.sharp, est <= 0.5)
    # the mask errs only within the tolerance of the margin
    assert np.all(exact[part.sharp] <= 0.5 + 1.5e-4 * 40)


def test_part_noise_is_absolute_in_millimetres():
    clean, noisy = hs.cad_part(5000), hs.cad_part(5000, noise=0.05)
    np.testing.assert_array_equal(clean.clean_points, noisy.clean_points)
    np.testing.assert_array_equal(clean.points, clean.clean_points)
    assert np.std(noisy.points - noisy.clean_points) == pytest.approx(0.05, rel=0.05)
    assert noisy.quantum == 0.0 and noisy.noise == 0.05


def test_edge_distance_helper_against_brute_force_segments():
    rng = np.random.default_rng(1)
    edges = [rng.uniform(0, 1, (k, 3)) for k in (2, 3, 6)]
    points = rng.uniform(-0.5, 1.5, (3000, 3))
    est = scenes._edge_distance(points, edges, size=1.0)
    exact = np.full(points.shape[0], np.inf)
    for e in edges:
        for s0, s1 in zip(e[:-1], e[1:]):
            d = s1 - s0
            t = np.clip((points - s0) @ d / (d @ d), 0.0, 1.0)
            exact = np.minimum(exact, np.linalg.norm(points - (s0 + t[:, None] * d), axis=1))
    assert np.all(est <= exact + 1e-12)
    near = exact <= 0.05
    assert near.sum() > 10 and (~near).sum() > 1000
    assert np.max(exact[near] - est[near]) <= 1e-4 + 1e-12
    assert np.max(exact - est) <= 2e-3 + 1e-12
