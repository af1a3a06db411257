"""heatcurv.cli.geodesic: ``heatcurv geodesic`` writes the distance along the surface."""

import numpy as np
import pytest
from cli_helpers import assert_one_line_error, run

from heatcurv import io, surfaces


@pytest.fixture(scope="module")
def sphere_file(tmp_path_factory):
    points = surfaces.Sphere().sample(3000, "random", seed=0).points
    path = tmp_path_factory.mktemp("geodesic") / "sphere.ply"
    io.write_points(path, points)
    return path, points


def great_circle(points, sources):
    return np.arccos(np.clip(points @ points[sources].T, -1.0, 1.0)).min(axis=1)


def test_distance_from_rows_and_from_coordinates(sphere_file, tmp_path, records):
    path, points = sphere_file
    out = run("geodesic", path, "-o", tmp_path / "d.npz", "--source", "0,7", "--source", "12")
    assert out.returncode == 0, out.stderr
    assert "geodesic distance from 3 source(s) over 3000 distinct points" in out.stdout
    with np.load(tmp_path / "d.npz") as archive:
        assert archive.files == ["points", "geodesic_distance"]
        distance = archive["geodesic_distance"]
    assert distance.dtype == np.float32 and np.all(distance[[0, 7, 12]] == 0)
    exact = great_circle(points, [0, 7, 12])
    others = exact > 0
    records.check("cli_geodesic/sphere-random-3000-three-sources",
                  mean=100 * float(np.mean(np.abs(distance[others] - exact[others]) / exact[others])))
    # --near picks the nearest point: a point just off row 5 is row 5
    near = ",".join(f"{c:.6f}" for c in 1.01 * points[5])
    out = run("geodesic", path, "-o", tmp_path / "n.csv", "--near", near, "-q", "--float64")
    assert out.returncode == 0, out.stderr
    by_near = io.read_points(tmp_path / "n.csv").fields["geodesic_distance"]
    out = run("geodesic", path, "-o", tmp_path / "s.csv", "--source", "5", "-q", "--float64")
    np.testing.assert_array_equal(io.read_points(tmp_path / "s.csv").fields["geodesic_distance"], by_near)


def test_coincident_points_share_a_distance_and_nonfinite_rows_get_nan(tmp_path):
    points = surfaces.Sphere().sample(2000, "random", seed=1).points
    cloud = np.vstack([points, points[:10], [[np.nan, 0.0, 0.0]]])
    path = tmp_path / "dup.xyz"
    np.savetxt(path, cloud)
    out = run("geodesic", path, "-o", tmp_path / "d.csv", "--source", "3")
    assert_one_line_error(out)
    assert "NaN or infinite coordinates" in out.stderr and "--skip-nonfinite" in out.stderr
    out = run("geodesic", path, "-o", tmp_path / "d.csv", "--source", "3", "--skip-nonfinite", "-q")
    assert out.returncode == 0, out.stderr
    distance = io.read_points(tmp_path / "d.csv").fields["geodesic_distance"]
    assert np.isnan(distance[-1]) and np.all(np.isfinite(distance[:-1]))
    np.testing.assert_array_equal(distance[2000:2010], distance[:10])
    out = run("geodesic", path, "-o", tmp_path / "d.csv", "--source", str(len(cloud) - 1), "--skip-nonfinite")
    assert_one_line_error(out)
    assert "that row has NaN or infinite coordinates" in out.stderr


@pytest.mark.parametrize("args, message", [
    ((), "give the sources"),
    (("--source", "3000"), "has 3000 points (rows 0 to 2999)"),
    (("--source", "x"), "expected point indices"),
    (("--source", "-2"), "expected point indices"),
    (("--near", "1,2"), "three numbers"),
])
def test_bad_sources_are_one_line_errors(sphere_file, tmp_path, args, message):
    path, _ = sphere_file
    out = run("geodesic", path, "-o", tmp_path / "d.ply", *args)
    assert_one_line_error(out)
    assert message in out.stderr
    assert not (tmp_path / "d.ply").exists()
