"""heatcurv.cli.compute: ``heatcurv compute`` writes every field, next to the input's properties."""

import re

import numpy as np
import pytest
from cli_helpers import WRITTEN, run

import heatcurv
from heatcurv import io


def test_compute_sphere_mean_curvature_is_one(sphere_fields_ply):
    out, out_path = sphere_fields_ply
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""  # messages go to stdout; no terminal, no progress bar
    assert "read " in out.stdout and f"wrote {out_path}" in out.stdout
    cloud = io.read_points(out_path)
    reliable = cloud.fields["reliable"].astype(bool)
    assert reliable.mean() > 0.95
    # unit sphere, outward normals: mean = k1 = k2 = 1, Gaussian 1, area 4 pi
    assert abs(np.median(cloud.fields["mean"]) - 1.0) < 0.01
    assert np.all(np.abs(cloud.fields["mean"][reliable] - 1.0) < 0.05)
    assert np.all(np.abs(cloud.fields["gaussian"][reliable] - 1.0) < 0.1)
    assert abs(cloud.fields["area"].sum() / (4 * np.pi) - 1.0) < 0.02
    assert np.all(np.einsum("ij,ij->i", cloud.normals, cloud.points) > 0.99)


@pytest.mark.parametrize("ext", [".ply", ".las", ".laz", ".csv", ".npz"])
def test_compute_round_trip_keeps_values_and_properties(
    workdir, sphere_ply, sphere_fields_ply, sphere_cloud, sphere_reference, ext
):
    points, colors, intensity = sphere_cloud
    if ext == ".ply":
        out, out_path = sphere_fields_ply
        assert out.returncode == 0, out.stderr
    else:
        out_path = workdir / f"round_trip{ext}"
        out = run("compute", sphere_ply, "-o", out_path, "--quiet")
        assert out.returncode == 0, out.stderr
        assert out.stdout == ""  # --quiet
    back = io.read_points(out_path)
    res = sphere_reference
    # the input's properties are kept
    np.testing.assert_array_equal(back.colours, colors)
    np.testing.assert_array_equal(back.fields["intensity"], intensity)
    atol = 2e-6 if ext in (".las", ".laz") else 0.0  # LAS stores scaled integer coordinates
    np.testing.assert_allclose(back.points, points, rtol=0, atol=atol)
    # every field, as computed in this process
    np.testing.assert_allclose(back.normals, res.normals, rtol=1e-9, atol=1e-12)
    for name in ("mean", "gaussian", "k1", "k2", "area"):
        np.testing.assert_allclose(back.fields[name], getattr(res, name), rtol=1e-9, atol=1e-12, err_msg=name)
    for vector in ("d1", "d2"):
        stacked = np.column_stack([back.fields[vector + axis] for axis in "xyz"])
        np.testing.assert_allclose(stacked, getattr(res, vector), rtol=1e-9, atol=1e-12, err_msg=vector)
    np.testing.assert_array_equal(back.fields["reliable"].astype(bool), res.reliable)
    names = [name for name in back.fields if name in WRITTEN]
    assert names == [name for name in WRITTEN if name not in ("nx", "ny", "nz")]


def test_ply_output_has_exactly_the_named_properties(sphere_fields_ply):
    import plyfile

    out, out_path = sphere_fields_ply
    assert out.returncode == 0, out.stderr
    names = list(plyfile.PlyData.read(str(out_path))["vertex"].data.dtype.names)
    assert names == ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "intensity", *WRITTEN[3:]]


def test_compute_field_subset_and_features(tmp_path, sphere_ply):
    out_path = tmp_path / "subset.npz"
    out = run("compute", sphere_ply, "-o", out_path, "--fields", "mean,k1,d1,feature_score", "-q")
    assert out.returncode == 0, out.stderr
    with np.load(out_path) as archive:
        assert sorted(archive.files) == sorted(["points", "colors", "intensity", "mean", "k1", "d1", "feature_score"])
        assert archive["d1"].shape == (3000, 3)
    out = run("compute", sphere_ply, "-o", tmp_path / "features.ply", "--features", "-q")
    back = io.read_points(tmp_path / "features.ply")
    assert list(back.fields)[-3:] == ["reliable", "feature", "feature_score"]
    assert back.fields["feature"].sum() == 0  # a smooth sphere has no sharp features


def test_normals_from_input_and_viewpoint_set_the_signs(tmp_path, sphere_cloud):
    points = sphere_cloud[0]
    path = tmp_path / "inward.ply"
    io.write_points(path, points, normals=-points)
    out = run("compute", path, "-o", tmp_path / "a.ply", "--normals-from-input", "-q")
    assert out.returncode == 0, out.stderr
    assert abs(np.median(io.read_points(tmp_path / "a.ply").fields["mean"]) + 1.0) < 0.01
    # a sensor inside the sphere: normals turn inwards, curvature negative (negative values parse)
    out = run("compute", path, "-o", tmp_path / "b.ply", "--viewpoint", "-0.1,0,0.05", "-q")
    assert out.returncode == 0, out.stderr
    back = io.read_points(tmp_path / "b.ply")
    assert abs(np.median(back.fields["mean"]) + 1.0) < 0.01
    assert np.all(np.einsum("ij,ij->i", back.normals, points) < 0)


def test_skip_nonfinite_rows(tmp_path, sphere_cloud):
    points = sphere_cloud[0].copy()
    points[[5, 70]] = np.nan
    path = tmp_path / "holes.npy"
    np.save(path, points)
    out = run("compute", path, "-o", tmp_path / "out.ply", "--skip-nonfinite", "-q")
    assert out.returncode == 0, out.stderr
    back = io.read_points(tmp_path / "out.ply")
    finite = np.isfinite(points).all(axis=1)
    assert np.isnan(back.fields["mean"][~finite]).all() and not back.fields["reliable"][~finite].any()
    res = heatcurv.estimate(points[finite])
    np.testing.assert_allclose(back.fields["mean"][finite], res.mean, rtol=1e-9)


def test_verbose_prints_stage_timings_and_the_kernel(workdir, sphere_ply):
    # a global option before the command (the round trips give --quiet after it)
    out = run("-v", "compute", sphere_ply, "-o", workdir / "verbose.ply")
    assert out.returncode == 0, out.stderr
    # the default method's fit stage (named "principal" before the core named each stage of the chord fit)
    assert re.search(r"curvature_fit\s+\d+\.\d+ s", out.stdout), out.stdout
    assert "chord-fit kernel: chord-60 (60 neighbours" in out.stdout
