"""heatcurv.orient.visibility: a point not reliable on a closed object faces the side its rays escape from."""

import dataclasses

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv._kernels.visibility import escaping_rays
from heatcurv.orient.visibility import CONE, NOISE_CLEARANCE, _fan, escape_votes, escaping_turns, lowest_keys, own_layer
from heatcurv.tuning import TUNING


def _reference_escapes(origins, directions, reach, centres, axes, radii):
    """Every ray against every disc with numpy: the rays that hit none beyond ``reach``."""
    out = np.zeros(len(origins), dtype=np.int64)
    reach = np.broadcast_to(reach, directions.shape[1:2])
    for a, o in enumerate(origins):
        for r, d in enumerate(directions[a]):
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.einsum("ij,ij->i", centres - o, axes) / (axes @ d)
                off = o + t[:, None] * d - centres
                hit = (t > reach[r]) & (np.einsum("ij,ij->i", off, off) <= radii**2)
            out[a] += not hit.any()
    return out


def test_ray_kernel_matches_numpy():
    rng = np.random.default_rng(4)
    centres = rng.uniform(-1, 1, size=(400, 3))
    axes = rng.normal(size=(400, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    radii = rng.uniform(0.02, 0.12, size=400)
    origins = rng.uniform(-1.2, 1.2, size=(300, 3))
    directions = rng.normal(size=(300, 7, 3))
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    directions[:5, 0] = [1.0, 0.0, 0.0]  # along a grid axis: the walk's ties
    for reach in (0.05, np.linspace(0.0, 0.6, 7)):  # one for every ray, or one per ray of the fan
        got = escaping_rays(origins, directions, reach, centres, axes, radii)
        want = _reference_escapes(origins, directions, reach, centres, axes, radii)
        assert 0 < want.sum() < 300 * 7  # rays both hit and escape
        np.testing.assert_array_equal(got, want)
    assert not np.array_equal(want, _reference_escapes(origins, directions, 0.05, centres, axes, radii))


def test_the_fan_is_unit_rays_around_each_normal():
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, 0.0, -0.8]])
    fan = _fan(normals)
    assert fan.shape == (3, sum(count for _, count in CONE), 3)
    np.testing.assert_allclose(np.linalg.norm(fan, axis=2), 1.0)
    cosines = np.einsum("rkj,rj->rk", fan, normals)
    want = np.concatenate([np.full(count, np.cos(np.radians(angle))) for angle, count in CONE])
    np.testing.assert_allclose(cosines, np.broadcast_to(want, cosines.shape), atol=1e-12)


def test_outward_normals_of_closed_surfaces_escape_along_and_not_against():
    # a sphere and a torus (its hole too: rays along the inner normals leave through the hole's openings)
    for name in ("sphere", "torus"):
        s = surfaces.get(name).sample(3000, "random", seed=2)
        votes = escape_votes(s.points, s.normals, s.points, s.normals)
        assert votes.min() > TUNING.escape_margin, name
        np.testing.assert_allclose(escape_votes(s.points, -s.normals, s.points, s.normals), -votes)


def test_a_thin_part_turned_inside_out_is_turned_back():
    # an ellipsoid 1 x 1 x 0.12 is a plate about 4 spacings thick at 3000 points: a point turned over
    # faces the other face, whose discs stop every ray along it, while its outside is open
    points, normals = _ellipsoid(3000, 0.12)
    wrong = np.random.default_rng(0).random(3000) < 0.1
    turned = np.where(wrong[:, None], -normals, normals)
    turn = escaping_turns(points, turned, np.ones(3000, dtype=bool), points, normals)
    assert np.array_equal(turn, wrong)
    # only tested points turn
    some = np.arange(3000) % 2 == 0
    assert np.array_equal(escaping_turns(points, turned, some, points, normals), wrong & some)


def test_a_closed_pocket_sees_no_escape_either_way():
    # points inside a closed sphere, facing any way: every ray hits it
    s = surfaces.get("sphere").sample(4000, "random", seed=1)
    inner = surfaces.get("sphere").sample(200, "random", seed=5)
    votes = escape_votes(0.5 * inner.points, inner.normals, s.points, s.normals)
    assert np.all(votes == 0)


def _noisy_tube(n, height, seed=1, noise=0.006):
    """An open tube of radius 1, noise ``noise`` of its diagonal: points, outward normals, the noise's deviation."""
    s = surfaces.Cylinder(1.0, height).sample(n, "random", noise=noise, seed=seed)
    outward = s.clean_points * [1.0, 1.0, 0.0]
    return s.points, outward / np.linalg.norm(outward, axis=1, keepdims=True), s.sigma


def test_on_a_noisy_surface_the_noise_layer_is_the_points_own_surface():
    # an open noisy tube, every normal outward: a point low in the noise layer has its outward rays stopped
    # by its neighbours' discs while its inward ones leave through the open ends (measured: 771 of 3000 turned)
    points, outward, sigma = _noisy_tube(3000, 1.0)
    tested = np.ones(len(points), dtype=bool)
    assert escaping_turns(points, outward, tested, points, outward).sum() > 500
    # past the layer of NOISE_CLEARANCE deviations (farther along a slanted ray) they escape outward
    assert escaping_turns(points, outward, tested, points, outward, own_layer(sigma, 1.0)).sum() == 0
    # the layer holds only where the residual is noise
    assert own_layer(sigma, 1.0) == NOISE_CLEARANCE * sigma
    assert own_layer(sigma, TUNING.noise_rise * 1.01) == own_layer(sigma, np.nan) == 0.0


def test_a_noisy_open_tube_keeps_its_side():
    # as short as it is wide, its sides' levels disagree (undecided) and every point is tested: without the
    # noise layer 775 of its 3000 points turned inside out
    points, outward, _ = _noisy_tube(3000, 1.0)
    with pytest.warns(heatcurv.HeatcurvWarning, match="cannot tell whether the cloud encloses a volume"):
        res = heatcurv.estimate(points)
    assert res.info["scale"].residual_rise < TUNING.noise_rise
    assert np.all(np.einsum("ij,ij->i", res.normals, outward) > 0) and res.info["orientation"].escaped == 0


def test_past_the_cap_the_lowest_keys_are_tested():
    keys = np.array([9, 3, 7, 1, 8], dtype=np.uint64)
    np.testing.assert_array_equal(lowest_keys(keys, 2), [1, 3])
    np.testing.assert_array_equal(lowest_keys(keys, 10), np.arange(5))


def _ellipsoid(n, c, seed=3):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    points = u * [1.0, 1.0, c]
    normals = points / np.array([1.0, 1.0, c]) ** 2
    return points, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def test_the_estimator_turns_only_points_not_reliable_and_their_curvatures_with_them(monkeypatch):
    # an ellipsoid 1 x 0.3 x 0.12 at 1200 points: its rim a few spacings thick, where the winding number
    # flags 25 points and leaves 5 of them inside out
    rng = np.random.default_rng(7)
    u = rng.normal(size=(1200, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    points, axes = u * [1.0, 0.3, 0.12], np.array([1.0, 0.3, 0.12])
    truth = points / axes**2
    res = heatcurv.estimate(points)
    assert res.info["orientation"].closed
    monkeypatch.setattr("heatcurv.orient.visibility.TUNING", dataclasses.replace(TUNING, escape_margin=2.0))
    kept = heatcurv.estimate(points)
    assert kept.info["orientation"].escaped == 0
    turned = np.einsum("ij,ij->i", res.normals, kept.normals) < 0
    assert turned.sum() == res.info["orientation"].escaped == 5
    assert not np.any(res.reliable[turned])
    assert np.all(np.einsum("ij,ij->i", res.normals[turned], truth[turned]) > 0)  # each one turned outward
    np.testing.assert_array_equal(res.reliable, kept.reliable)
    np.testing.assert_allclose(res.mean, np.where(turned, -kept.mean, kept.mean))
    np.testing.assert_allclose(res.k1, np.where(turned, -kept.k2, kept.k1))
    np.testing.assert_allclose(res.gaussian, kept.gaussian)
    np.testing.assert_allclose(res.k1_se, np.where(turned, kept.k2_se, kept.k1_se))
