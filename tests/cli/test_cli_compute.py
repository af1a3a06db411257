"""heatcurv.cli.compute: ``heatcurv compute`` writes every field, next to the input's properties."""

import re

import numpy as np
import pytest
from cli_helpers import WRITTEN, run, stderr_lines

import heatcurv
from heatcurv import io
from heatcurv.data import bunny_path


def test_compute_sphere_mean_curvature_is_one(sphere_fields_ply):
    out, out_path = sphere_fields_ply
    assert out.returncode == 0, out.stderr
    assert stderr_lines(out) == []  # messages go to stdout; no terminal, no progress bar
    assert "read " in out.stdout and f"wrote {out_path}" in out.stdout
    area = re.search(r"surface area ([0-9.e+-]+) \(reliable points: ([0-9.e+-]+)\)", out.stdout)
    assert area and abs(float(area.group(1)) / (4 * np.pi) - 1.0) < 0.02
    cloud = io.read_points(out_path)
    reliable = cloud.fields["reliable"].astype(bool)
    assert reliable.mean() > 0.95
    # unit sphere, outward normals: mean = k1 = k2 = 1, Gaussian 1, area 4 pi
    assert abs(np.median(cloud.fields["mean"]) - 1.0) < 0.01
    assert np.all(np.abs(cloud.fields["mean"][reliable] - 1.0) < 0.05)
    assert np.all(np.abs(cloud.fields["gaussian"][reliable] - 1.0) < 0.1)
    assert abs(cloud.fields["area"].sum() / (4 * np.pi) - 1.0) < 0.02
    assert np.all(np.einsum("ij,ij->i", cloud.normals, cloud.points) > 0.99)


@pytest.mark.parametrize(
    "ext,float64",
    [(".ply", False), (".las", False), (".laz", False), (".csv", False), (".npz", False), (".ply", True),
     (".laz", True)],
)
def test_compute_round_trip_keeps_values_and_properties(
    workdir, sphere_ply, sphere_fields_ply, sphere_cloud, sphere_reference, ext, float64
):
    points, colors, intensity = sphere_cloud
    if ext == ".ply" and not float64:
        out, out_path = sphere_fields_ply
        assert out.returncode == 0, out.stderr
    else:
        out_path = workdir / f"round_trip{'_64' if float64 else ''}{ext}"
        out = run("compute", sphere_ply, "-o", out_path, "--quiet", *(["--float64"] if float64 else []))
        assert out.returncode == 0, out.stderr
        assert out.stdout == ""  # --quiet
    back = io.read_points(out_path)
    res = sphere_reference
    # the input's properties are kept
    np.testing.assert_array_equal(back.colours, colors)
    np.testing.assert_array_equal(back.fields["intensity"], intensity)
    atol = 2e-6 if ext in (".las", ".laz") else 0.0  # LAS stores scaled integer coordinates
    np.testing.assert_allclose(back.points, points, rtol=0, atol=atol)  # coordinates never narrowed
    # every field, as computed in this process: float32 in binary formats unless --float64
    narrow = ext != ".csv" and not float64
    rtol = 1.2e-7 if narrow else 1e-9  # float32 keeps 7 significant digits
    expected_type = np.float32 if narrow else np.float64
    assert back.normals.dtype == np.float64  # read as float64, whatever the file stores
    assert back.fields["mean"].dtype == expected_type
    np.testing.assert_allclose(back.normals, res.normals, rtol=rtol, atol=1e-12)
    for name in ("mean", "gaussian", "k1", "k2", "area"):
        np.testing.assert_allclose(back.fields[name], getattr(res, name), rtol=rtol, atol=1e-12, err_msg=name)
    for vector in ("d1", "d2"):
        stacked = np.column_stack([back.fields[vector + axis] for axis in "xyz"])
        np.testing.assert_allclose(stacked, getattr(res, vector), rtol=rtol, atol=1e-12, err_msg=vector)
    np.testing.assert_array_equal(back.fields["reliable"].astype(bool), res.reliable)
    assert ext == ".csv" or back.fields["reliable"].dtype.kind in "bu"  # text is read as float64
    names = [name for name in back.fields if name in WRITTEN]
    assert names == [name for name in WRITTEN if name not in ("nx", "ny", "nz")]


def test_float32_by_default_makes_a_laz_much_smaller(workdir, sphere_fields_ply):
    """The issue: every field was float64, a LAZ grew 10x; float32 by default, --float64 on request."""
    out, ply = sphere_fields_ply
    assert out.returncode == 0, out.stderr
    source = workdir / "sphere_source.laz"
    cloud = io.read_points(ply)
    io.write_points(source, cloud.points, {"intensity": cloud.fields["intensity"]}, colours=cloud.colours)
    sizes = {}
    for flag in ((), ("--float64",)):
        path = workdir / f"sizes{''.join(flag)}.laz"
        done = run("compute", source, "-o", path, "-q", *flag)
        assert done.returncode == 0, done.stderr
        sizes[flag] = path.stat().st_size
        import laspy

        written = laspy.read(path).point_format
        kind = np.float64 if flag else np.float32
        assert written.dimension_by_name("mean").dtype == kind
        assert written.dimension_by_name("reliable").dtype == np.uint8
    assert sizes[()] < 0.6 * sizes[("--float64",)], sizes


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
        # the documented field names, one array each, as in every other format
        assert archive.files == [
            "points", "red", "green", "blue", "intensity", "mean", "k1", "d1x", "d1y", "d1z", "feature_score"
        ]
        assert archive["d1x"].shape == (3000,) and archive["mean"].dtype == np.float32
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
    out = run(
        "compute", path, "-o", tmp_path / "out.ply", "--skip-nonfinite", "-q", "--fields", "mean,reliable,neighbours"
    )
    assert out.returncode == 0, out.stderr
    back = io.read_points(tmp_path / "out.ply")
    finite = np.isfinite(points).all(axis=1)
    assert np.isnan(back.fields["mean"][~finite]).all() and not back.fields["reliable"][~finite].any()
    # counts stay integers: 0 neighbours on the rows not computed (not NaN in a float column)
    assert back.fields["neighbours"].dtype == np.int32 and not back.fields["neighbours"][~finite].any()
    res = heatcurv.estimate(points[finite])
    np.testing.assert_allclose(back.fields["mean"][finite], res.mean, rtol=1.2e-7)
    np.testing.assert_array_equal(back.fields["neighbours"][finite], res.neighbours)


def test_verbose_prints_stage_timings_and_the_kernel(workdir, sphere_ply):
    # a global option before the command (the round trips give --quiet after it)
    out = run("-v", "compute", sphere_ply, "-o", workdir / "verbose.ply")
    assert out.returncode == 0, out.stderr
    # the default method's fit stage (named "principal" before the core named each stage of the chord fit)
    assert re.search(r"curvature_fit\s+\d+\.\d+ s", out.stdout), out.stdout
    assert "fit plan: chord-60, at every point (clean)" in out.stdout
    assert "kernel: chord-60 (60 neighbours" in out.stdout


def test_a_noisy_cloud_writes_its_per_point_kernel_radius(tmp_path):
    # the chosen radius per point as an output field, the plan, the anchors and support in --verbose
    sample = heatcurv.surfaces.Torus().sample(5000, "random", noise=0.003, seed=1)
    path = tmp_path / "noisy.npy"
    np.save(path, sample.points)
    out = run("-v", "compute", path, "-o", tmp_path / "out.ply", "--fields", "mean,fit_radius")
    assert out.returncode == 0, out.stderr
    assert re.search(r"fit plan: denoised-\d+, at anchors \(16 per ball\), carried to every point", out.stdout)
    assert re.search(r"fitted at \d+ anchors; support radius", out.stdout), out.stdout
    assert "very low noise" not in out.stdout
    back = io.read_points(tmp_path / "out.ply")
    res = heatcurv.estimate(sample.points)
    np.testing.assert_allclose(back.fields["fit_radius"], res.fit_radius, rtol=1e-6)
    assert res.info["scale"].median_radius == pytest.approx(np.median(res.fit_radius), rel=1e-9)


def test_verbose_says_when_the_very_low_noise_path_ran(tmp_path):
    # noise of 1e-5 of the diagonal takes the low-noise path: --verbose and the report say so
    points = heatcurv.surfaces.Torus().sample(8000, "random", noise=1e-5, seed=3).points
    np.save(tmp_path / "rounded.npy", points)
    out = run("-v", "compute", tmp_path / "rounded.npy", "-o", tmp_path / "out.ply", "--fields", "mean")
    assert out.returncode == 0, out.stderr
    assert "very low noise (such as millimetre rounding)" in out.stdout, out.stdout
    assert re.search(r"fit plan: denoised-\d+, at anchors \(24 per ball\), carried to every point by a degree-3 "
                     r"regression of their tensors; low-noise refit", out.stdout), out.stdout
    assert heatcurv.estimate(points).info["scale"].low_noise


def test_ply_mesh_keeps_its_faces_and_other_formats_warn(tmp_path):
    import plyfile

    sample = heatcurv.surfaces.Sphere().sample(800, "fibonacci")
    vertex = np.zeros(800, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("quality", "f4")])
    for k, axis in enumerate("xyz"):
        vertex[axis] = sample.points[:, k]
    faces = np.zeros(500, dtype=[("vertex_indices", "i4", (3,))])
    faces["vertex_indices"] = np.random.default_rng(1).integers(0, 800, (500, 3))
    mesh = tmp_path / "mesh.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex"), plyfile.PlyElement.describe(faces, "face")]).write(
        str(mesh)
    )
    out = run("compute", mesh, "-o", tmp_path / "out.ply", "-q")
    assert out.returncode == 0 and out.stderr == "", out.stderr
    written = plyfile.PlyData.read(str(tmp_path / "out.ply"))
    np.testing.assert_array_equal(np.vstack(written["face"].data["vertex_indices"]), faces["vertex_indices"])
    assert written["vertex"].data.dtype["x"] == np.dtype("<f4")  # the input's coordinate type
    for ext in (".laz", ".csv"):
        out = run("compute", mesh, "-o", tmp_path / f"out{ext}", "-q")
        assert out.returncode == 0, out.stderr
        assert out.stderr == (
            f"heatcurv: warning: the 500 faces of {mesh} are not written to {tmp_path / f'out{ext}'} "
            f"({ext} holds points only; write a .ply to keep them)\n"
        )


@pytest.mark.parametrize("spelling", ["same", "dotted", "symlink", "hardlink"])
def test_output_equal_to_the_input_is_refused(tmp_path, sphere_ply, spelling):
    import os
    import shutil

    from cli_helpers import assert_one_line_error

    directory = tmp_path / "data"
    directory.mkdir()
    original = directory / "scan.ply"
    shutil.copy(sphere_ply, original)
    before = original.read_bytes()
    output = {
        "same": original,
        "dotted": directory / ".." / "data" / "." / "scan.ply",
        "symlink": tmp_path / "link.ply",
        "hardlink": tmp_path / "hard.ply",
    }[spelling]
    if spelling == "symlink":
        output.symlink_to(original)
    elif spelling == "hardlink":
        os.link(original, output)
    for command in (["compute"], ["features"]):
        out = run(*command, original, "-o", output)
        assert_one_line_error(out)
        assert "it is the input file" in out.stderr and "choose another output name" in out.stderr
        assert "read " not in out.stdout  # refused before reading
    assert original.read_bytes() == before
    assert sorted(p.name for p in directory.iterdir()) == ["scan.ply"]


def test_unwritable_output_fails_before_reading(tmp_path, sphere_ply, monkeypatch, capsys):
    from cli_helpers import assert_one_line_error

    from heatcurv.cli import main, steps

    blocker = tmp_path / "not_a_directory"
    blocker.write_text("a file where a directory should be")
    out = run("compute", sphere_ply, "-o", blocker / "out.ply")
    assert_one_line_error(out)
    assert f"cannot write {blocker / 'out.ply'}: {blocker} is not a directory" in out.stderr
    assert "read " not in out.stdout and "estimated" not in out.stdout

    # a read-only file or directory (as an ordinary user sees it; root may write anything)
    import os
    import subprocess

    kept = tmp_path / "kept.ply"
    kept.write_bytes(b"protected")
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(kept) else real_access(p, mode))
    estimated = []
    monkeypatch.setattr(steps, "read_cloud", lambda *a, **k: estimated.append(a))
    status = main(["compute", str(sphere_ply), "-o", str(kept)])
    captured = capsys.readouterr()
    assert_one_line_error(subprocess.CompletedProcess([], status, captured.out, captured.err))
    assert "kept.ply: the file exists and is read-only" in captured.err
    assert estimated == [] and kept.read_bytes() == b"protected"


def test_las_input_is_oriented_up_by_default(tmp_path):
    # aerial LiDAR: normals towards the sky unless told otherwise; --orient outward is obeyed
    tile = heatcurv.surfaces.lidar_tile(6000, seed=4)
    src = tmp_path / "tile.laz"
    io.write_points(src, tile.points)
    ground = tile.labels == 2
    out = run("compute", str(src), "-o", str(tmp_path / "up.ply"))
    assert out.returncode == 0, out.stderr
    assert "orienting normals up (+z)" in out.stdout
    up = io.read_points(tmp_path / "up.ply")
    assert (up.normals[ground, 2] > 0).mean() >= 0.995
    out = run("compute", str(src), "-o", str(tmp_path / "out.ply"), "--orient", "outward", "-v")
    assert out.returncode == 0, out.stderr
    assert "orienting normals up" not in out.stdout and "orientation: outward" in out.stdout


def test_compute_says_what_the_winding_number_did(tmp_path):
    # the shipped bunny scan: its thin ears are where the spanning tree and the winding number disagree
    res = heatcurv.estimate(io.read_points(str(bunny_path())).points)
    report = res.info["orientation"]
    assert report.closed and report.turned > 0 and report.unsupported > 0
    out = run("compute", bunny_path(), "-o", tmp_path / "b.ply")
    assert out.returncode == 0, out.stderr
    text = out.stdout + out.stderr
    assert f"{report.turned} point(s) of parts the spanning tree had turned inside out were turned outward" in text
    assert f"{report.ambiguous} point(s) have no consistent side" in text and "the winding number contradicts" in text


def test_compute_says_which_side_the_default_chose(tmp_path):
    # an NPY terrain (no LAS header to say "aerial"): the default still orients it up, and says why
    tile = heatcurv.surfaces.lidar_tile(6000, seed=4)
    np.save(tmp_path / "tile.npy", tile.points)
    out = run("compute", tmp_path / "tile.npy", "-o", tmp_path / "up.ply", "-v")
    assert out.returncode == 0, out.stderr
    assert "normals oriented up (+z): the cloud is an open surface over the horizontal plane" in out.stdout
    assert "orientation chosen: auto: an open surface over the horizontal plane" in out.stdout
    up = io.read_points(tmp_path / "up.ply")
    assert (up.normals[tile.labels == 2, 2] > 0).mean() >= 0.995
    # the same terrain stood on its side is over its own plane, across y: too flat for a convex side,
    # so the axis's largest coordinate (y) is made positive, a convention
    np.save(tmp_path / "side.npy", tile.points[:, [0, 2, 1]])
    out = run("compute", tmp_path / "side.npy", "-o", tmp_path / "side.ply")
    assert out.returncode == 0, out.stderr
    assert "the axis's largest coordinate positive, a convention: the cloud is an open surface over the plane" \
        in out.stdout
    side = io.read_points(tmp_path / "side.ply")
    assert (side.normals[tile.labels == 2, 1] > 0).mean() >= 0.995
    # an open arc of a tube (240 degrees) is over no plane: outward, by each piece's convex side
    tube = heatcurv.surfaces.get("cylinder").sample(8000, "random", seed=1).points
    np.save(tmp_path / "arc.npy", tube[tube[:, 0] > -0.5])
    out = run("compute", tmp_path / "arc.npy", "-o", tmp_path / "arc.ply")
    assert out.returncode == 0, out.stderr
    assert "normals oriented outward of each piece (its convex side)" in out.stdout
    assert "normals oriented up" not in out.stdout and "normals oriented along" not in out.stdout


def test_compute_refuses_a_las_whose_records_are_misaligned(tmp_path):
    """One byte inserted in the points of a LAS: exit 2, one line, no output (it used to compute garbage, exit 0)."""
    points = heatcurv.surfaces.Sphere().sample(400, "fibonacci").points * 2 + 10
    source = tmp_path / "sphere.las"
    io.write_points(source, points)
    data = source.read_bytes()
    offset, record_length = int.from_bytes(data[96:100], "little"), int.from_bytes(data[105:107], "little")
    at = offset + 7 * record_length + 3
    source.write_bytes(data[:at] + b"\x00" + data[at:])
    out = run("compute", source, "-o", tmp_path / "out.ply")
    assert out.returncode == 2, out.stdout + out.stderr
    assert out.stderr == (
        f"heatcurv: error: cannot read {source}: the point data holds {400 * record_length + 1} bytes, 1 more than "
        f"the 400 points of {record_length} bytes the header announces (not a whole number of records): the point "
        "count, the record length or the offset to the points is wrong, or bytes were inserted\n")
    assert not (tmp_path / "out.ply").exists()


def test_a_radius_below_the_spacing_says_so_and_names_one_that_works(tmp_path):
    out = run("compute", bunny_path(), "-o", tmp_path / "out.ply", "--radius", "0.0001")
    assert out.returncode == 0, out.stderr
    assert stderr_lines(out) == [
        "heatcurv: warning: radius = 0.0001 leaves a median point's ball with 0 neighbours; the chord fit has 9 "
        "unknowns and needs at least 10, so many points will be unreliable. The points' median spacing is 0.28: "
        "radius = 0.7 gives 90 % of them at least 10 neighbours"
    ]
    assert "0 of 1839 points reliable" in out.stdout
    out = run("compute", bunny_path(), "-o", tmp_path / "out.ply", "--radius", "0.7")
    assert out.returncode == 0 and stderr_lines(out) == [], out.stderr
    assert "1409 of 1839 points reliable" in out.stdout


def test_compute_writes_the_standard_errors_on_request(workdir, sphere_ply, sphere_reference):
    """``--fields errors``: five float32 columns, the library's values to float32's rounding."""
    path = workdir / "sphere_errors.npz"
    out = run("compute", sphere_ply, "-o", path, "--fields", "mean,errors")
    assert out.returncode == 0, out.stderr
    cloud = io.read_points(path)
    names = ["mean_se", "gaussian_se", "k1_se", "k2_se", "normal_se"]
    assert [name for name in cloud.fields if name != "intensity"] == ["mean"] + names
    for name in names:
        values = cloud.fields[name]
        assert values.dtype == np.float32 and np.all(np.isfinite(values)) and np.all(values > 0), name
        np.testing.assert_allclose(values, getattr(sphere_reference, name), rtol=2e-6, err_msg=name)


@pytest.mark.parametrize("fields, computed", [(None, False), ("mean,k1_se", True)])
def test_compute_computes_the_standard_errors_only_when_written(workdir, sphere_ply, sphere_reference, monkeypatch,
                                                                fields, computed):
    """Without an error field the estimate skips them (they change no other field): ``se`` reaches it."""
    from heatcurv import estimator
    from heatcurv.cli.main import main

    seen = []
    real = estimator.estimate
    monkeypatch.setattr(estimator, "estimate", lambda *a, **k: seen.append(k.get("se", True)) or real(*a, **k))
    path = workdir / f"sphere_se_{computed}.npz"
    assert main(["compute", str(sphere_ply), "-o", str(path), "-q"] + (["--fields", fields] if fields else [])) == 0
    assert seen == [computed]
    cloud = io.read_points(path)
    assert ("k1_se" in cloud.fields) == computed
    for name in ("mean", "k1_se") if computed else ("mean", "k1", "reliable", "area"):
        np.testing.assert_allclose(cloud.fields[name], getattr(sphere_reference, name).astype(np.float32),
                                   rtol=2e-6, err_msg=name)


def test_standard_errors_with_the_papers_method_are_refused_before_any_work(workdir, sphere_ply):
    path = workdir / "paper_errors.ply"
    out = run("compute", sphere_ply, "-o", path, "--fields", "k1_se", "--method", "paper")
    assert out.returncode == 2
    assert "k1_se: standard errors come with the default method's kernel choice, not with --method paper" in out.stderr
    assert "read " not in out.stdout and not path.exists()
