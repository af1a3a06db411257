"""heatcurv.orient.orientation: outward, up and towards a scanner; thin parts; what cannot be oriented is flagged."""

import dataclasses

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.errors import HeatcurvError
from heatcurv.geometry.neighbourhood import knn_neighbourhood
from heatcurv.orient.normals import pca_normals
from heatcurv.orient.orientation import as_viewpoint, local_sides, orient
from heatcurv.tuning import TUNING


def _knn(points, k=60):
    return knn_neighbourhood(points, k)


def _worst_angle_deg(normals, exact):
    """The largest angle between oriented unit normals and the exact ones, degrees (atan2: exact at small angles)."""
    sine = np.linalg.norm(np.cross(normals, exact), axis=1)
    return float(np.degrees(np.arctan2(sine, np.einsum("ij,ij->i", normals, exact)).max()))


def _shortfall(agree):
    """% of the points that disagree (the records hold errors: 100 - % agreeing)."""
    return 100 * (1 - np.mean(agree))


def _scrambled(normals, seed=0):
    return normals * np.random.default_rng(seed).choice([-1.0, 1.0], size=(len(normals), 1))


def rounded_disk(n, a=1.0, t=0.05, seed=0):
    """A closed thin disc (radius ``a``, thickness ``2 t``, rim a half torus of tube ``t``) and its outward normals."""
    rng = np.random.default_rng(seed)
    flat_area, rim_area = 2 * np.pi * a**2, 2 * np.pi * np.pi * t * a + 4 * np.pi * t**2
    n_rim = int(n * rim_area / (flat_area + rim_area))
    m = n - n_rim
    r, th, side = a * np.sqrt(rng.random(m)), rng.uniform(0, 2 * np.pi, m), rng.choice([-1.0, 1.0], m)
    flat, flat_n = np.c_[r * np.cos(th), r * np.sin(th), side * t], np.c_[np.zeros((m, 2)), side]
    # the rim's area element is (a + t cos v) t: rejection sampling
    u, v = rng.uniform(0, 2 * np.pi, 4 * n_rim), rng.uniform(-np.pi / 2, np.pi / 2, 4 * n_rim)
    keep = rng.random(4 * n_rim) < (a + t * np.cos(v)) / (a + t)
    u, v = u[keep][:n_rim], v[keep][:n_rim]
    rim_n = np.c_[np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)]
    rim = np.c_[a * np.cos(u), a * np.sin(u), np.zeros(n_rim)] + t * rim_n
    return np.vstack([flat, rim]), np.vstack([flat_n, rim_n])


def test_thin_disc_stays_outward(records):
    # a closed disc 0.1 thick whose balls (radius about 0.1) reach across to the other side, like a
    # bunny's ear: the plain Hoppe cost 1 - |n_i . n_j| takes the edges across, whose normals are
    # parallel, for the cheapest and turned one side inside out (measured: 50 % of the normals); the
    # tilt term keeps the tree in the surface
    pts, normals = rounded_disk(15000)
    res = heatcurv.estimate(pts)
    outward = np.einsum("ij,ij->i", res.normals, normals) > 0
    assert outward.mean() >= 0.995
    records.check("orientation/thin-disc-15000", inward=_shortfall(outward))
    assert res.info["orientation"].mode == "outward"


def test_sharp_edges_are_crossed_consistently(records):
    # a cube: at its edges n_i . n_j is about 0 and its sign is noise; the normals' agreement across
    # the edge (components along the edge removed) is 0.5 and decides
    rng = np.random.default_rng(7)
    face = rng.integers(0, 6, 12000)
    uv = rng.uniform(-1, 1, (12000, 2))
    axis, sign = face // 2, np.where(face % 2 == 0, 1.0, -1.0)
    pts = np.empty((12000, 3))
    normals = np.zeros((12000, 3))
    for k in range(3):
        on = axis == k
        others = [j for j in range(3) if j != k]
        pts[on, k] = sign[on]
        pts[np.ix_(on, others)] = uv[on]
        normals[on, k] = sign[on]
    nb = _knn(pts)
    nrm, _ = pca_normals(pts, nb)
    got = orient(pts, _scrambled(nrm, 1), nb)
    outward = np.einsum("ij,ij->i", got.normals, normals) > 0
    assert outward.mean() >= 0.995
    records.check("orientation/cube-12000-pca", inward=_shortfall(outward))


def test_outward_on_a_torus_from_scrambled_normals(torus_sample, records):
    pts = torus_sample.points
    nb = _knn(pts)
    nrm, _ = pca_normals(pts, nb)
    got = orient(pts, _scrambled(nrm), nb)
    assert np.all(np.einsum("ij,ij->i", got.normals, torus_sample.normals) > 0)  # every one outward
    worst = _worst_angle_deg(got.normals, torus_sample.normals)
    records.check("orientation/torus-fibonacci-8000-pca", normal_max_deg=worst)
    assert got.report.components == 1 and got.report.ambiguous == 0 and not got.ambiguous.any()


def test_up_orients_a_lidar_tile_to_the_sky(records):
    tile = surfaces.lidar_tile(12000, seed=1)
    surface = tile.labels != 5  # the vegetation has no normal
    res = heatcurv.estimate(tile.points, orient="up")
    agree = np.einsum("ij,ij->i", res.normals[surface], tile.normals[surface]) > 0
    # ground and roofs face the sky, walls (no up or down) face out of their building, from their roofs
    assert agree.mean() >= 0.995
    walls = tile.labels[surface] == 66
    assert agree[walls].mean() >= 0.99
    report = res.info["orientation"]
    assert report.mode == "up" and report.anchored >= (tile.labels == 2).sum()
    # hill tops bend away from the up normal, valleys towards it
    convex, concave = res.mean[tile.convex & res.reliable] > 0, res.mean[tile.concave & res.reliable] < 0
    assert convex.mean() >= 0.99 and concave.mean() >= 0.99
    records.check(
        "orientation/lidar-tile-12000-up", wrong_side=_shortfall(agree), wrong_side_walls=_shortfall(agree[walls]),
        wrong_sign_convex=_shortfall(convex), wrong_sign_concave=_shortfall(concave),
    )


def test_up_agrees_with_a_random_half(records):
    tile = surfaces.lidar_tile(12000, seed=2)
    full = heatcurv.estimate(tile.points, orient="up")
    half = np.flatnonzero(np.random.default_rng(2).random(len(tile.points)) < 0.5)
    part = heatcurv.estimate(tile.points[half], orient="up")
    agree = np.einsum("ij,ij->i", full.normals[half], part.normals) > 0
    surface = tile.labels[half] != 5
    assert agree[surface].mean() >= 0.995
    records.check("orientation/lidar-tile-12000-up-half", disagree=_shortfall(agree[surface]))


def test_up_accepts_another_up_direction(records):
    tile = surfaces.lidar_tile(6000, seed=3)
    pts = tile.points - tile.points.mean(axis=0)
    yz = pts[:, [0, 2, 1]] * [1, 1, -1]  # the same scene with +y up
    nb = _knn(yz)
    nrm, _ = pca_normals(yz, nb)
    got = orient(yz, nrm, nb, mode="up", towards=(0, 2.0, 0))
    ground = tile.labels == 2
    assert (got.normals[ground, 1] > 0).mean() >= 0.995
    records.check("orientation/lidar-tile-6000-up-y", wrong_side_ground=_shortfall(got.normals[ground, 1] > 0))


def test_viewpoint_faces_the_scanner_everywhere_after_the_fit(records):
    # a range scan of a sphere from one side: every final normal faces the scanner, grazing points too
    sample = surfaces.Sphere(radius=1.0).scan(6000, viewpoints=[[0.0, 0.0, 6.0]], seed=3)
    res = heatcurv.estimate(sample.points, viewpoint=(0.0, 0.0, 6.0))
    facing = np.einsum("ij,ij->i", res.normals, [0.0, 0.0, 6.0] - sample.points)
    assert np.all(facing > 0)
    assert res.info["orientation"].mode == "viewpoint"
    # the flipped points' curvatures were flipped with them: a sphere seen from outside is convex
    assert np.median(res.mean[res.reliable]) > 0
    records.check("orientation/sphere-scan-6000-viewpoint", median_mean=100 * (np.median(res.mean[res.reliable]) - 1))
    assert np.all(res.k1 >= res.k2)


def test_per_point_scanner_positions():
    # the inside and the outside of a sphere, each seen from its own scanner: an (n, 3) viewpoint
    sample = surfaces.Sphere(radius=1.0).sample(4000, "fibonacci")
    pts = sample.points
    scanner = np.where(pts[:, 2:3] > 0, [0.0, 0.0, 5.0], [0.0, 0.0, 0.0])
    res = heatcurv.estimate(pts, viewpoint=scanner)
    facing = np.einsum("ij,ij->i", res.normals, scanner - pts)
    assert np.all(facing > 0)
    with pytest.raises(HeatcurvError, match=r"viewpoint must be 3 finite numbers .* or an \(4000, 3\) array"):
        heatcurv.estimate(pts, viewpoint=scanner[:10])


def test_moebius_strip_is_flagged_not_guessed(records):
    # a non-orientable surface: no consistent side exists, so the seam must be flagged ambiguous
    rng = np.random.default_rng(5)
    u, v = rng.uniform(0, 2 * np.pi, 20000), rng.uniform(-0.3, 0.3, 20000)
    pts = np.c_[(1 + v * np.cos(u / 2)) * np.cos(u), (1 + v * np.cos(u / 2)) * np.sin(u), v * np.sin(u / 2)]
    nb = _knn(pts)
    nrm, _ = pca_normals(pts, nb)
    got = orient(pts, nrm, nb)
    # the seam is where the propagation closes the loop: a band across the strip, few points
    assert 0 < got.ambiguous.sum() < 0.1 * len(pts)
    seam_u = u[got.ambiguous]
    spread = np.abs(np.angle(np.exp(1j * (seam_u - np.angle(np.exp(1j * seam_u).mean())))))
    assert np.median(spread) < 0.2  # one place along the strip, not scattered
    records.check("orientation/moebius-20000-pca", seam_spread_deg=np.degrees(np.median(spread)))
    res = heatcurv.estimate(pts)
    assert res.info["orientation"].ambiguous > 0
    assert res.reliable.sum() <= len(pts) - res.info["orientation"].ambiguous


def test_vertical_wall_alone_cannot_be_oriented_up():
    # no normal faces up or down: nothing tells the sides apart, so every point is ambiguous
    rng = np.random.default_rng(6)
    pts = np.c_[rng.uniform(-1, 1, 3000), np.zeros(3000), rng.uniform(0, 1, 3000)]
    res = heatcurv.estimate(pts, orient="up")
    assert res.info["orientation"].ambiguous == len(pts)
    assert not res.reliable.any()


def test_clean_closed_surfaces_have_no_ambiguous_point(torus_sample):
    res = heatcurv.estimate(torus_sample.points)
    assert res.info["orientation"].ambiguous == 0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"orient": "viewpoint"}, "orient='viewpoint' needs viewpoint="),
        ({"orient": "up", "viewpoint": (0, 0, 1)}, "cannot be combined with orient='up'"),
        ({"orient": "sideways"}, "orient must be one of 'auto', 'outward', 'up', 'viewpoint'"),
        ({"orient": "up", "normals": "given"}, "the given normals are kept as they are"),
    ],
)
def test_bad_orientation_options(kwargs, message):
    pts = surfaces.Sphere().sample(500, "fibonacci").points
    if kwargs.get("normals") == "given":
        kwargs = {**kwargs, "normals": pts}
    with pytest.raises(HeatcurvError, match=message):
        heatcurv.estimate(pts, **kwargs)


def test_viewpoint_validation():
    np.testing.assert_array_equal(as_viewpoint((1, 2, 3)), [1.0, 2.0, 3.0])
    with pytest.raises(HeatcurvError, match="viewpoint must be 3 finite numbers"):
        as_viewpoint((1, 2, np.nan))
    with pytest.raises(HeatcurvError, match="viewpoint must be 3 finite numbers"):
        as_viewpoint("here")


def test_anchor_threshold_is_a_cosine():
    assert 0.0 < TUNING.anchor_cosine < 1.0
    # a point on the equator of a sphere oriented up has |n_z| < TUNING.anchor_cosine: it takes its side from
    # its neighbours, so the equator band comes out outward like the rest of the upper hemisphere
    sample = surfaces.Sphere().sample(8000, "fibonacci")
    upper = sample.points[:, 2] > -0.2
    pts = sample.points[upper]
    res = heatcurv.estimate(pts, orient="up")
    band = np.abs(sample.normals[upper][:, 2]) < TUNING.anchor_cosine
    assert np.all(np.einsum("ij,ij->i", res.normals[band], sample.normals[upper][band]) > 0)


def test_a_sheet_seen_from_both_sides_is_flagged(records):
    # a thin plate scanned from above and from below, each point facing its own scanner: within one
    # ball the two faces point opposite ways, so no side is right for the plate; flagged, not guessed
    rng = np.random.default_rng(8)
    n = 8000
    xy = rng.uniform(-1, 1, (n, 2))
    below = np.arange(n) % 2 == 1
    pts = np.c_[xy, np.where(below, -0.002, 0.002)]
    scanner = np.where(below[:, None], [0.0, 0.0, -5.0], [0.0, 0.0, 5.0])
    res = heatcurv.estimate(pts, viewpoint=scanner)
    assert np.all(np.einsum("ij,ij->i", res.normals, scanner - pts) > 0)  # each faces its scanner
    assert res.info["orientation"].ambiguous >= 0.9 * n
    assert res.reliable.mean() <= 0.1
    records.check(
        "orientation/two-sided-sheet-8000", unflagged=100 * (1 - res.info["orientation"].ambiguous / n),
        reliable=100 * res.reliable.mean(),
    )


def test_far_outliers_are_cut_out_of_the_orientation_graph():
    # before: three points 25 diagonals away bridged the spanning tree of a grid-sampled
    # torus and turned 272 of its 510 normals inward (ambiguous 53, the rest "reliable")
    sample = surfaces.Torus(0.6, 1.4).sample(500, "grid", seed=1)
    far = np.array([
        [61.68178366, 85.97149445, 98.02699437],
        [-50.07109424, -117.21154607, -67.52311388],
        [111.22988137, 88.72916014, -23.66604211],
    ])
    res = heatcurv.estimate(np.vstack([sample.points, far]))
    n = len(sample.points)
    assert res.outlier[n:].all() and not res.outlier[:n].any()
    assert np.all(np.einsum("ij,ij->i", res.normals[:n], sample.normals) > 0)
    assert res.info["orientation"].ambiguous == 0
    assert res.info["orientation"].components == 1  # the torus; the cut-out points are not surfaces
    assert np.all(res.mean[:n][res.reliable[:n]] > 0)  # a torus's mean curvature is positive


@pytest.mark.parametrize("surface", ["sphere", "torus"])
@pytest.mark.parametrize("distance", [5.0, 100.0, 1e4])
def test_one_to_three_far_points_never_flip_a_closed_surface(surface, distance):
    surf = surfaces.Sphere() if surface == "sphere" else surfaces.Torus(0.6, 1.4)
    sample = surf.sample(1500, "fibonacci")
    diag = np.linalg.norm(np.ptp(sample.points, axis=0))
    rng = np.random.default_rng(int(distance))
    for count in (1, 3):
        d = rng.normal(size=(count, 3))
        far = d / np.linalg.norm(d, axis=1)[:, None] * distance * diag
        res = heatcurv.estimate(np.vstack([sample.points, far]))
        n = len(sample.points)
        assert res.outlier[n:].all()
        assert np.all(np.einsum("ij,ij->i", res.normals[:n], sample.normals) > 0)


def _wall_on_ground(n=4000, height=3.0, seed=9):
    """A vertical wall (x = 0, 0 < z < height) standing on flat ground that lies on its +x side."""
    rng = np.random.default_rng(seed)
    m = n // 2
    ground = np.c_[rng.uniform(0.0, 3.0, m), rng.uniform(0.0, 4.0, m), np.zeros(m)]
    wall = np.c_[np.zeros(n - m), rng.uniform(0.0, 4.0, n - m), rng.uniform(0.0, height, n - m)]
    return np.vstack([ground, wall]), np.arange(n) >= m


def test_up_carries_the_ground_up_a_wall_round_by_round(records):
    # the ground faces up (anchors); the wall's normals are horizontal: each round of local_sides
    # carries the side one graph edge further up, out of the building (+x, towards the ground)
    pts, wall = _wall_on_ground()
    nb = _knn(pts, 30)
    nrm, _ = pca_normals(pts, nb)
    got = orient(pts, _scrambled(nrm, 2), nb, mode="up")
    rmax = nb.radius.max()
    # every side right; the PCA normals tilt within a ball of the crease, beyond it they are the planes' own
    assert np.all(got.normals[~wall, 2] > 0) and np.all(got.normals[wall, 0] > 0)
    exact = np.where(wall[:, None], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    far = np.where(wall, pts[:, 2], pts[:, 0]) > rmax
    records.check(
        "orientation/wall-on-ground-4000-up", tilt_max_deg=_worst_angle_deg(got.normals, exact),
        tilt_far_max_deg=_worst_angle_deg(got.normals[far], exact[far]),
    )
    assert got.report.anchored >= (~wall).sum() and got.report.ambiguous == 0
    # two rounds only: the foot of the wall is decided, the rest not yet
    graph = nb.spread(10)
    facing = nrm[:, 2]
    anchors = np.abs(facing) >= TUNING.anchor_cosine
    sides, reach = local_sides(pts, nrm, graph, np.where(anchors, np.sign(facing), 0.0), hops=2)
    decided = wall & ~anchors & (sides != 0)
    assert np.all(nrm[decided, 0] * sides[decided] > 0)  # +x
    # within two edges of the ground (each edge at most its row's ball radius), and not above
    assert pts[decided, 2].max() <= 2 * rmax
    assert np.all(sides[wall & (pts[:, 2] > 2 * rmax)] == 0) and decided.sum() >= 50
    # reach: an anchor's is its ball; a wall point's adds up its edges, at most two rounds of them
    np.testing.assert_array_equal(reach[anchors], nb.radius[anchors])
    assert np.all(reach[wall] >= nb.radius[wall]) and np.all(reach[wall] <= nb.radius[wall] + 3 * rmax)
    assert np.all(reach[decided] > nb.radius[decided])


def test_up_is_decided_within_its_reach():
    # the contract a tiled run relies on: a point whose reach lies inside a part of the cloud gets the
    # same side and the same ambiguity flag from that part alone as from the whole cloud
    tile = surfaces.lidar_tile(12000, seed=1)
    pts = tile.points - tile.points.mean(axis=0)
    nb = _knn(pts)
    whole = orient(pts, pca_normals(pts, nb)[0], nb, mode="up")
    part = pts[:, 0] < 0.0  # the western half
    nb_part = _knn(pts[part])
    got = orient(pts[part], pca_normals(pts[part], nb_part)[0], nb_part, mode="up")
    # a point's flag reads its neighbours' sides, each within its reach plus one ball of the point's
    reach = whole.reach[part] + nb.radius.max()
    inside = -pts[part, 0] > reach
    walls = tile.labels[part] == surfaces.BUILDING_WALL
    carried = inside & (whole.reach[part] > nb.radius[part])  # a side in the ball came from afar
    # measured: 4498 points, 122 of them on walls, 224 read a side carried from afar (reach up to
    # 12.5 m, ball radii 2.6 m)
    assert inside.sum() >= 4000 and (walls & inside).sum() >= 100 and carried.sum() >= 180
    assert np.all(np.einsum("ij,ij->i", got.normals[inside], whole.normals[part][inside]) > 0)
    np.testing.assert_array_equal(got.ambiguous[inside], whole.ambiguous[part][inside])
    assert np.all(whole.reach >= nb.radius)


def _ground_and_crown(seed=0):
    """A 60 x 60 m ground of 8000 points and a crown: 2000 points uniform in a ball of radius 5 m, 8 m up."""
    rng = np.random.default_rng(seed)
    ground = np.column_stack([rng.uniform(0, 60, (8000, 2)), 0.02 * rng.standard_normal(8000)])
    direction = rng.standard_normal((2000, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    crown = np.array([30.0, 30.0, 8.0]) + 5.0 * np.cbrt(rng.random(2000))[:, None] * direction
    return np.vstack([ground, crown]), np.arange(10000) >= 8000


@pytest.mark.parametrize("mode", ["up", "viewpoint"])
def test_a_ball_without_a_normal_axis_faces_the_reference_direction(mode):
    pts, crown = _ground_and_crown()
    nb = _knn(pts)
    nrm, _, roundness = pca_normals(pts, nb, roundness=True)
    towards = np.array([30.0, 30.0, 100.0]) if mode == "viewpoint" else None
    got = orient(pts, nrm, nb, mode=mode, towards=towards, roundness=roundness)
    axisless = roundness >= TUNING.axisless_ball
    # a uniform ball's smallest two variances are about equal: most crown balls, no ground ball (noise 2 cm,
    # balls ~2.5 m: lambda_0 / lambda_1 ~ 1e-4)
    assert axisless[crown].mean() >= 0.5 and not axisless[~crown].any()
    reference = np.broadcast_to([0.0, 0.0, 1.0], pts.shape) if mode == "up" else towards - pts
    reference = reference / np.linalg.norm(reference, axis=1)[:, None]
    np.testing.assert_allclose(got.normals[axisless], reference[axisless], atol=1e-15)
    assert got.report.axisless == axisless.sum()
    # the other points and every flag as without the rule (the estimator judges these points by their fit)
    plain = orient(pts, nrm, nb, mode=mode, towards=towards)
    np.testing.assert_array_equal(got.normals[~axisless], plain.normals[~axisless])
    np.testing.assert_array_equal(got.ambiguous, plain.ambiguous)
    assert plain.report.axisless == 0


def test_a_noisy_surface_whose_balls_have_no_axis_stays_reliable(monkeypatch):
    # noise of 0.6 % of the diagonal makes some of the operator's balls as round as a crown's; the fit over
    # its wider ball finds the surface (residual about the cloud's noise), so nothing is lost
    sample = surfaces.get("saddle").sample(20000, "random", seed=0, noise=0.006)
    pts = sample.points
    res = heatcurv.estimate(pts)
    assert res.info["orientation"].mode == "up" and res.info["orientation"].axisless >= 500  # measured 836
    for module in ("heatcurv.orient.orientation", "heatcurv.estimator"):
        monkeypatch.setattr(f"{module}.TUNING", dataclasses.replace(TUNING, axisless_ball=np.inf))
    plain = heatcurv.estimate(pts)
    assert plain.info["orientation"].axisless == 0
    # the refined normals start elsewhere at the round balls: measured 2 points newly reliable, none lost
    assert np.count_nonzero(res.reliable != plain.reliable) <= 10 and not (plain.reliable & ~res.reliable).any()
    # their fits move a little (normals 0.003 degrees, median), no closer to or further from the truth:
    # mean absolute error of the mean curvature over the 1127 moved points 0.07730 of its scale either way
    both = res.reliable & plain.reliable
    moved = both & (res.mean != plain.mean)
    error = [np.mean(np.abs(r.mean - sample.mean)[moved]) for r in (res, plain)]
    assert moved.sum() <= 2000 and abs(error[0] - error[1]) <= 1e-3 * error[1]


def test_a_crown_and_its_random_half_agree_where_the_pca_axis_does_not():
    pts, crown = _ground_and_crown()
    half = np.sort(np.random.default_rng(1).choice(len(pts), len(pts) // 2, replace=False))
    full, part = heatcurv.estimate(pts, orient="up"), heatcurv.estimate(pts[half], orient="up")
    assert not full.reliable[crown].any()
    assert "no normal axis" in full.info["orientation"].reason
    cosine = np.einsum("ij,ij->i", full.normals[half], part.normals)
    on_crown = crown[half]
    # the fit's refined normals start from up: measured 99.3 % of the crown facing up and the two runs
    # disagreeing on 2.1 % of it (92.2 % and 15.0 % with each ball's PCA axis and its neighbours' side)
    assert (full.normals[crown, 2] > 0).mean() >= 0.99 and (cosine[on_crown] < 0).mean() <= 0.03
    assert (cosine[~on_crown] > 0).all()
