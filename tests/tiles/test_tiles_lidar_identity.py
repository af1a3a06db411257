"""A LiDAR-like tile (ground, buildings, trees) forced into tiles equals the in-memory run, orientation included.

``orient="up"`` (the default for LAS/LAZ) once carried a wall's or a crown's
side from the nearest anchor along the spanning tree of the whole cloud, a
path a tile could not see: on ``lidar_tile(12000, seed=0)`` in 6 tiles, 53
points differed with ``orient="up"`` and 52 with a viewpoint (crown normals
flipped, and every value fitted with them). The side is now decided within a
few balls of each point (:func:`heatcurv.orient.orientation.local_sides`), which the
tiles' halo holds. Measured: the flags, counts, spacing and ball radii equal bit for bit,
the other fields within 4.1e-15 relative (mean curvature; normals 5.7e-16): rounding, which
the tests hold at 2e-14.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from tiles_helpers import ALL_FIELDS, read_fields

import heatcurv
from heatcurv.tiles import compute_file
from support.tiles import tiled_agreement

FIELDS = {"normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "area", "reliable", "spacing", "neighbours",
          "fit_radius", "border", "outlier"}


@pytest.fixture(scope="module")
def lidar_file(tmp_path_factory):
    """``lidar_tile(12000, seed=0)`` as an NPY file, and the scene."""
    scene = heatcurv.surfaces.lidar_tile(12000, seed=0)
    path = tmp_path_factory.mktemp("lidar") / "lidar.npy"
    np.save(path, scene.points)
    return path, scene


@pytest.mark.parametrize("orient", [{"orient": "up"}, {"viewpoint": (500010.0, 4999990.0, 1200.0)}, {}],
                         ids=["up", "viewpoint", "auto"])
def test_lidar_tile_in_tiles_equals_in_memory(lidar_file, tmp_path, orient):
    src, scene = lidar_file
    memory = heatcurv.estimate(scene.points, **orient)
    out = tmp_path / "lidar.ply"
    report = compute_file(src, out, tile_size=3000, scheduler="serial", dtype="float64", fields=ALL_FIELDS,
                          **orient)
    assert report.tiles >= 6 and report.points == 12000
    agreement = tiled_agreement(out, memory, rtol=2e-14)  # the masks and counts: exactly
    assert set(agreement) >= FIELDS
    assert {name: a["bad"] for name, a in agreement.items()} == dict.fromkeys(agreement, 0)
    assert all(agreement[name]["worst"] == 0.0 for name in ("reliable", "outlier", "border", "neighbours",
                                                               "spacing", "fit_radius"))
    # every side as in memory
    columns = read_fields(out)
    normals = np.column_stack([columns[a] for a in ("nx", "ny", "nz")])
    assert np.all(np.einsum("ij,ij->i", normals, memory.normals) > 0)
    if not orient:
        # no option, an NPY file: the survey's sample centres chose "up" as the in-memory run's did
        assert memory.info["orientation"].mode == "up" and "horizontal plane" in memory.info["orientation"].reason
        assert report.context["auto_orientation"] == "up"
    if "viewpoint" not in orient:
        # the walls out of their buildings, the ground and the roofs up (measured: every point)
        surface = scene.labels != heatcurv.surfaces.VEGETATION
        assert (np.einsum("ij,ij->i", normals[surface], scene.normals[surface]) > 0).mean() >= 0.999
    else:
        # a scanner 1 km above: every final normal faces it
        assert np.all(np.einsum("ij,ij->i", normals, np.asarray(orient["viewpoint"]) - scene.points) > 0)


def test_a_turned_lidar_tile_in_tiles_equals_in_memory(lidar_file, tmp_path):
    # no longer over the horizontal plane: the survey's sample orients it along its own axis, which every
    # tile then reads from the survey's context, as the in-memory run reads it from the same sample
    _, scene = lidar_file
    turn = Rotation.random(random_state=0).as_matrix()
    points = (scene.points - scene.points.mean(axis=0)) @ turn.T
    src = tmp_path / "turned.npy"
    np.save(src, points)
    memory = heatcurv.estimate(points)
    policy = memory.info["orientation"].policy
    assert policy.mode == "up" and policy.towards is not None
    out = tmp_path / "turned.ply"
    report = compute_file(src, out, tile_size=3000, scheduler="serial", dtype="float64", fields=ALL_FIELDS)
    assert report.tiles >= 6
    assert report.context["auto_orientation"] == "up"
    assert np.allclose(report.context["auto_towards"], policy.towards, rtol=0.0, atol=1e-12)
    agreement = tiled_agreement(out, memory, rtol=2e-14)
    assert {name: a["bad"] for name, a in agreement.items()} == dict.fromkeys(agreement, 0)
    columns = read_fields(out)
    normals = np.column_stack([columns[a] for a in ("nx", "ny", "nz")])
    assert np.all(np.einsum("ij,ij->i", normals, memory.normals) > 0)


ERRORS = ("mean_se", "k1_se", "k2_se", "gaussian_se", "normal_se")


@pytest.mark.parametrize("cloud", ["lidar", "noisy torus"])
def test_standard_errors_in_tiles_equal_in_memory(lidar_file, tmp_path, cloud):
    # the standard errors blend sample centres drawn by each point's own key and reach several balls
    # (heatcurv.fits.uncertainty): the first halo of a run that writes them holds them (measured: no tile
    # widened; the values equal to 7e-16 relative, rounding)
    if cloud == "lidar":
        src, scene = lidar_file
        points, options = scene.points, {"orient": "up"}
    else:
        points, options = heatcurv.surfaces.Torus().sample(12000, "random", noise=0.003, seed=1).points, {}
        src = tmp_path / "torus.npy"
        np.save(src, points)
    memory = heatcurv.estimate(points, **options)
    out = tmp_path / "errors.ply"
    report = compute_file(src, out, tile_size=3000, scheduler="serial", dtype="float64",
                          fields=("nx", "ny", "nz", "mean", "k1", "k2") + ERRORS, **options)
    assert report.tiles >= 6 and report.widened == 0
    agreement = tiled_agreement(out, memory, rtol=2e-14)
    assert set(agreement) >= set(ERRORS)
    assert {name: a["bad"] for name, a in agreement.items()} == dict.fromkeys(agreement, 0)
    # a point without a fit (an outlier) has infinite standard errors in both
    assert np.array_equal(np.isinf(read_fields(out)["mean_se"]), np.isinf(memory.mean_se))
