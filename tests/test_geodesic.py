"""Geodesic distance by the heat method (heatcurv.operators.geodesic) against exact distances.

The sphere's exact distance is the great circle's; the torus's comes from an
exact polyhedral geodesic on a fine triangulation through the cloud's points
(tests/support/geodesics.py, stored in tests/data/torus_geodesic.npz); on a
plane it is the straight line. Errors are the mean relative error over every
point but the sources, in %.
"""

from pathlib import Path

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.errors import HeatcurvError
from heatcurv.operators import geodesic

TORUS = Path(__file__).with_name("data") / "torus_geodesic.npz"


def mean_relative_error(distance, exact):
    others = exact > 0
    return 100.0 * float(np.mean(np.abs(distance[others] - exact[others]) / exact[others]))


@pytest.fixture(scope="module")
def sphere():
    points = surfaces.Sphere().sample(10000, "random", seed=0).points
    return points, heatcurv.PointCloudLaplacian(points)


def great_circle(points, sources):
    cosine = points @ points[np.atleast_1d(sources)].T
    return np.arccos(np.clip(cosine, -1.0, 1.0)).min(axis=1)


def test_random_sphere_against_the_great_circle(sphere, records):
    points, lap = sphere
    distance = lap.geodesic_distance(0)
    assert distance[0] == 0.0
    error = mean_relative_error(distance, great_circle(points, 0))
    assert error < 0.5  # the accuracy heatcurv promises on random spheres and tori (docs/laplacian.md, table 5)
    records.check("geodesic/sphere-random-10000", mean=error)


def test_several_sources_give_the_distance_to_the_nearest(sphere, records):
    points, lap = sphere
    sources = [0, 1, 2, 3]
    distance = lap.geodesic_distance(sources)
    assert np.all(distance[sources] == 0.0)
    records.check("geodesic/sphere-random-10000-four-sources",
                  mean=mean_relative_error(distance, great_circle(points, sources)))


def test_random_torus_against_exact_polyhedral_geodesics(records):
    stored = np.load(TORUS)
    points = surfaces.Torus().sample(stored["points"].shape[0], "random", seed=0).points
    np.testing.assert_allclose(points, stored["points"], atol=1e-6)  # the cloud the reference was made for
    distance = heatcurv.PointCloudLaplacian(points).geodesic_distance(0)
    error = mean_relative_error(distance, stored["distance"])
    assert error < 0.5  # as on the sphere; 0.45 % here (0.46 % at 20 000 points, table 5)
    records.check("geodesic/torus-random-10000", mean=error)


def test_plane_gives_the_straight_line_also_from_a_corner(records):
    points = surfaces.Plane().sample(5000, "random", seed=0).points
    lap = heatcurv.PointCloudLaplacian(points)
    centre = int(np.argmin(np.linalg.norm(points - points.mean(axis=0), axis=1)))
    corner = int(np.argmin(points[:, 0] + points[:, 1]))
    errors = {name: mean_relative_error(lap.geodesic_distance(source), np.linalg.norm(points - points[source], axis=1))
              for name, source in (("centre", centre), ("corner", corner))}
    records.check("geodesic/plane-random-5000", **errors)


def test_the_curved_chord_near_a_source_is_the_great_circle_to_third_order(sphere, records):
    points, lap = sphere
    lap.geodesic_distance(0)  # builds the solver
    method = lap._geodesics
    arc = great_circle(points, 0)
    near = (arc > 0) & (arc < geodesic.RING[1] * method.spacing)  # where the ring and the near field read it
    chord = np.linalg.norm(points - points[0], axis=1)
    curved, flat = method.near_distance(np.array([0]))
    assert flat[near].all()  # a sphere's cap of 16 spacings is flat enough for its quadric
    errors = {"chord_max": 100 * np.max(np.abs(chord - arc)[near] / arc[near]),
              "curved_max": 100 * np.max(np.abs(curved - arc)[near] / arc[near])}
    assert errors["curved_max"] < errors["chord_max"] / 10
    records.check("geodesic/sphere-random-10000-near-source", **errors)


def test_distances_scale_with_the_units_and_are_symmetric(sphere):
    points, lap = sphere
    scaled = heatcurv.PointCloudLaplacian(1000.0 * points + 5e4).geodesic_distance(7)
    np.testing.assert_allclose(scaled, 1000.0 * lap.geodesic_distance(7), rtol=1e-6, atol=1e-6)
    there, back = lap.geodesic_distance(5)[77], lap.geodesic_distance(77)[5]
    exact = great_circle(points, 5)[77]
    # each within the method's error of the truth (0.5 % on average here), so within 2 % of each other
    assert abs(there - back) < 0.02 * exact


def test_gradient_is_exact_on_linear_functions_and_the_divergence_is_its_adjoint():
    points = surfaces.Plane().sample(2000, "random", seed=1).points
    lap = heatcurv.PointCloudLaplacian(points)
    lap.geodesic_distance(0)
    method = lap._geodesics
    slope = np.array([0.3, -0.7, 0.0])
    f = points @ slope
    np.testing.assert_allclose(method.gradient(f), np.tile(slope, (len(points), 1)), atol=1e-12)
    # for a linear f with gradient X, S1 f = div X at every point (interior and border alike)
    divergence = method.divergence(np.tile(slope, (len(points), 1)))
    np.testing.assert_allclose(lap.first_order @ f, divergence, atol=1e-12 * np.abs(divergence).max())


def test_a_faint_heat_gives_the_same_directions(sphere, monkeypatch):
    # far from the source of a large cloud the heat is ~1e-200 and its gradient's square underflows;
    # the directions, and so the distances, must not depend on the heat's scale
    _, lap = sphere
    lap.geodesic_distance(0)  # builds the solver
    method = lap._geodesics
    usual = method.distance(np.array([3]))
    heat = method.heat
    monkeypatch.setattr(method, "heat", lambda sources: 1e-250 * heat(sources))
    np.testing.assert_allclose(method.distance(np.array([3])), usual, rtol=1e-9, atol=1e-12)


def test_pieces_without_a_source_are_infinitely_far():
    ball = surfaces.Sphere().sample(3000, "random", seed=0).points
    lap = heatcurv.PointCloudLaplacian(np.vstack([ball, ball + [5.0, 0.0, 0.0]]))
    one = lap.geodesic_distance(0)
    assert np.all(np.isinf(one[3000:])) and np.all(np.isfinite(one[:3000]))
    both = lap.geodesic_distance([0, 3000])
    np.testing.assert_allclose(both[3000:], both[:3000], atol=1e-9)  # the same sphere, the same source


def test_a_heat_step_too_short_for_the_cloud_is_lengthened(sphere, monkeypatch):
    points, _ = sphere
    lap = heatcurv.PointCloudLaplacian(points[:3000])
    usual = lap.geodesic_distance(0)
    monkeypatch.setattr(geodesic, "HEAT_FLOOR", 1e-3)  # as if the heat had left the floating-point range
    longer = heatcurv.PointCloudLaplacian(points[:3000])
    distance = longer.geodesic_distance(0)
    assert longer._geodesics.time > 4.0 * lap._geodesics.time
    assert mean_relative_error(distance, great_circle(points[:3000], 0)) < 5.0  # blurred, not lost
    assert np.all(np.isfinite(distance)) and np.all(np.isfinite(usual))
    monkeypatch.setattr(geodesic, "LONGER_STEPS", 0)
    with pytest.raises(HeatcurvError, match="too long and thin"):
        heatcurv.PointCloudLaplacian(points[:3000]).geodesic_distance(0)


@pytest.mark.parametrize("sources, message", [
    (-1, r"in \[0, 9999\]"), (10000, r"in \[0, 9999\]"), ([], "a point index"), (1.5, "a point index"),
    (True, "got booleans"), (np.arange(10000) < 3, r"got booleans; for a mask pass np\.flatnonzero"),
    ([[0, 1]], "a point index"), ("0", "a point index"),
])
def test_bad_sources_are_named(sphere, sources, message):
    _, lap = sphere
    with pytest.raises(HeatcurvError, match=message):
        lap.geodesic_distance(sources)
