"""The command line, run as a subprocess like a user would, on files the tests write."""

import io as stdio
import re
import subprocess
import sys

import numpy as np
import pytest

import heatcurv
from heatcurv import cli, io, surfaces
from heatcurv.data import BUNNY_ATTRIBUTION, bunny_path

#: Scalar fields compute writes by default, in the written order.
WRITTEN = ["nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area", "reliable"]


def run(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "heatcurv", *map(str, args)], capture_output=True, text=True, timeout=180, cwd=cwd
    )


def assert_one_line_error(out, *, status=2):
    assert out.returncode == status, (out.returncode, out.stderr)
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("heatcurv: error: "), out.stderr
    assert "Traceback" not in out.stderr + out.stdout


# ----------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("cli")


@pytest.fixture(scope="module")
def sphere_cloud():
    """3000 random points on the unit sphere, with colours and an intensity property."""
    sample = surfaces.Sphere().sample(3000, "random", seed=3)
    rng = np.random.default_rng(0)
    colors = rng.integers(0, 256, size=(3000, 3))
    intensity = rng.integers(0, 65536, size=3000).astype(np.uint16)
    return sample.points, colors, intensity


@pytest.fixture(scope="module")
def sphere_ply(workdir, sphere_cloud):
    points, colors, intensity = sphere_cloud
    path = workdir / "sphere.ply"
    io.write_points(path, points, {"intensity": intensity}, colors=colors)
    return path


@pytest.fixture(scope="module")
def sphere_fields_ply(workdir, sphere_ply):
    """``heatcurv compute sphere.ply -o sphere_fields.ply``: the process and its output."""
    path = workdir / "sphere_fields.ply"
    return run("compute", sphere_ply, "-o", path), path


@pytest.fixture(scope="module")
def sphere_reference(sphere_cloud):
    """The library run in this process on the same points."""
    return heatcurv.estimate(sphere_cloud[0])


# ----------------------------------------------------------------------------- demo, help


def test_demo_prints_an_error_table(tmp_path):
    out = run("demo", "--surface", "sphere", "-n", "3000", "--sampler", "fibonacci", "--no-picture", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "sphere, 3000 points" in out.stdout
    rows = {line.split()[0]: line.split() for line in out.stdout.splitlines() if re.match(r"^(default|paper) ", line)}
    assert set(rows) == {"default", "paper"}
    # columns: mean k1 k2 gauss area d1 normal orient time; sphere: the paper's < 1 %
    assert float(rows["paper"][1]) < 1.0
    assert float(rows["default"][1]) < 0.05
    assert abs(float(rows["paper"][5])) < 0.2  # total area, %
    assert rows["default"][8] == "100.00%"
    assert list(tmp_path.iterdir()) == []  # --no-picture


def test_bad_arguments_give_one_line_and_status_2():
    out = run("demo", "-n", "3")
    assert out.returncode == 2
    assert out.stderr.strip() == "heatcurv: error: n must be at least 4, got 3"
    assert "Traceback" not in out.stderr


def test_debug_shows_the_traceback():
    out = run("--debug", "demo", "-n", "3", "--no-picture")
    assert out.returncode != 0 and "Traceback" in out.stderr


def test_help_and_version():
    assert "demo" in run("--help").stdout
    assert run("--version").stdout.startswith("heatcurv ")
    assert run().returncode == 2  # a subcommand is required


@pytest.mark.parametrize(
    "command, option",
    [("compute", "--normals-from-input"), ("render", "--views"), ("features", "--threshold"), ("info", "input"), ("demo", "--surface")],
)
def test_help_of_every_subcommand(command, option, capsys):
    # in this process: the real process's --help is tested above
    assert cli.main([command, "--help"]) == 0
    out = capsys.readouterr()
    assert out.out.startswith(f"usage: heatcurv {command}") and out.err == ""
    assert option in out.out


def test_demo_default_on_a_random_cloud_writes_a_picture(tmp_path):
    # the default example: random sampling, where the paper's areas fail
    out = run("demo", "-n", "6000", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    rows = {line.split()[0]: line.split() for line in out.stdout.splitlines() if re.match(r"^(default|paper) ", line)}
    # measured at 6000 points: default mean 0.20 %, area +0.11 %; paper area -51 %
    assert float(rows["default"][1]) < 0.5 and abs(float(rows["default"][5])) < 0.5
    assert float(rows["paper"][5]) < -20
    assert "wrote heatcurv_demo.png" in out.stdout
    image = read_image(tmp_path / "heatcurv_demo.png")
    assert image.shape[:2] == (1000, 1400) and distinct_colours(image) > 100


def test_demo_on_the_bunny(tmp_path):
    out = run("demo", "--bunny", "-o", "bunny.png", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "1839 points" in out.stdout and BUNNY_ATTRIBUTION in out.stdout
    image = read_image(tmp_path / "bunny.png")
    assert image.shape[:2] == (800, 1600) and distinct_colours(image) > 100


def test_the_bunny_ships_with_its_attribution():
    path = bunny_path()
    header = path.read_bytes()[:400].decode("ascii")
    assert f"comment {BUNNY_ATTRIBUTION}\n" in header
    assert "element vertex 1839" in header
    assert (path.parent / "README.md").is_file()


# ----------------------------------------------------------------------------- compute


def read_image(path):
    from matplotlib.image import imread

    return imread(path)


def distinct_colours(image) -> int:
    pixels = np.round(np.asarray(image)[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    return np.unique(pixels, axis=0).shape[0]


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
def test_compute_round_trip_keeps_values_and_properties(workdir, sphere_ply, sphere_fields_ply, sphere_cloud, sphere_reference, ext):
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
    np.testing.assert_array_equal(back.colors, colors)
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


def test_features_command_finds_the_crease(tmp_path):
    fold = surfaces.FoldedSquare(interior_angle=90).sample(2500, "random", seed=0)
    path = tmp_path / "fold.xyz"
    io.write_points(path, fold.points)
    out = run("features", path, "-o", tmp_path / "fold.csv")
    assert out.returncode == 0, out.stderr
    assert "sharp features:" in out.stdout
    back = io.read_points(tmp_path / "fold.csv")
    assert list(back.fields) == ["feature", "feature_score"]
    mask = back.fields["feature"].astype(bool)
    distance = fold.fold_distance
    assert mask.sum() > 20
    # measured: 159 features, median distance to the fold 0.038, farthest 0.09 (the square is 2 wide)
    assert np.median(distance[mask]) < 0.05 and distance[mask].max() < 0.15


def test_verbose_prints_stage_timings_and_the_kernel(workdir, sphere_ply):
    # a global option before the command (the round trips give --quiet after it)
    out = run("-v", "compute", sphere_ply, "-o", workdir / "verbose.ply")
    assert out.returncode == 0, out.stderr
    assert re.search(r"principal\s+\d+\.\d+ s", out.stdout), out.stdout
    assert "chord-fit kernel: chord-60 (60 neighbours" in out.stdout


# ----------------------------------------------------------------------------- info


def test_info_on_the_bunny_and_on_computed_fields(workdir, sphere_ply):
    out = run("info", bunny_path())
    assert out.returncode == 0, out.stderr
    assert re.search(r"^points\s+1839 \(1839 distinct\)$", out.stdout, flags=re.MULTILINE), out.stdout
    assert "PLY (ascii)" in out.stdout and "normals      no" in out.stdout
    assert re.search(r"median distance to the nearest neighbour 0\.28\d+", out.stdout)
    out = run("info", sphere_ply)
    assert re.search(r"^points\s+3000 ", out.stdout, flags=re.MULTILINE)
    assert "colours      yes" in out.stdout and "intensity" in out.stdout
    assert re.search(r"x\s+-0\.99\d+ \.\. 0\.99\d+", out.stdout)


def test_info_reports_nonfinite_rows(tmp_path):
    path = tmp_path / "nan.xyz"
    path.write_text("0 0 0\n1 0 0\nnan 1 1\n0 1 0\n1 1 1\n")
    out = run("info", path)
    assert out.returncode == 0, out.stderr
    assert "points       5 (4 distinct)" in out.stdout
    assert "non-finite   1 row(s)" in out.stdout


# ----------------------------------------------------------------------------- errors


def _write_bad_inputs(directory):
    """Bad input files by case name."""
    rng = np.random.default_rng(0)
    files = {}
    good = rng.normal(size=(3000, 3))
    for ext in (".ply", ".las"):
        full = directory / f"full{ext}"
        io.write_points(full, good)
        data = full.read_bytes()
        (directory / f"truncated{ext}").write_bytes(data[: len(data) // 2])
        files[f"truncated{ext}"] = directory / f"truncated{ext}"
    (directory / "garbage.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\n" + rng.bytes(500))
    (directory / "garbage.las").write_bytes(rng.bytes(3000))
    (directory / "empty.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    (directory / "zero_bytes.xyz").write_bytes(b"")
    (directory / "nan_rows.xyz").write_text("0 0 0\n1 0 0\nnan 1 1\n0 1 0\n1 1 1\n0.5 0.5 0\n")
    (directory / "too_few.xyz").write_text("0 0 0\n1 0 0\n0 1 0\n")
    np.save(directory / "line.npy", np.outer(np.arange(100.0), [1.0, 2.0, 3.0]))
    (directory / "table.csv").write_text("name,age\nbob,42\nalice,37\n")
    (directory / "image.ply").write_bytes(b"\x89PNG\r\n\x1a\n" + rng.bytes(300))
    (directory / "scan.e57").write_bytes(b"not supported")
    for name in ("garbage.ply", "garbage.las", "empty.ply", "zero_bytes.xyz", "nan_rows.xyz", "too_few.xyz",
                 "line.npy", "table.csv", "image.ply", "scan.e57"):
        files[name] = directory / name
    files["missing"] = directory / "missing.ply"
    files["directory"] = directory / "a_directory.ply"
    files["directory"].mkdir()
    return files


@pytest.fixture(scope="module")
def bad_inputs(tmp_path_factory):
    return _write_bad_inputs(tmp_path_factory.mktemp("bad"))


BAD_FILES = {
    "missing": "no such file",
    "directory": "directory",
    "scan.e57": "unknown extension '.e57'; supported: .ply .las",
    "zero_bytes.xyz": "empty",
    "truncated.ply": "not a valid PLY file",
    "garbage.ply": "not a valid PLY file",
    "truncated.las": "not a valid LAS/LAZ file",
    "garbage.las": "not a valid LAS/LAZ file",
    "empty.ply": "no points",
    "nan_rows.xyz": "NaN or infinite coordinates (rows 2,",
    "too_few.xyz": "too few points",
    "line.npy": "lie on one line",
    "table.csv": "cannot read",
    "image.ply": "not a valid PLY file",
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_input_files(tmp_path, bad_inputs, case):
    output = tmp_path / "out.ply"
    out = run("compute", bad_inputs[case], "-o", output)
    assert_one_line_error(out)
    assert BAD_FILES[case] in out.stderr
    assert list(tmp_path.iterdir()) == []  # no output, no temporary file


BAD_OPTIONS = {
    "viewpoint with two numbers": (["--viewpoint", "1,2"], "argument --viewpoint: expected three numbers X,Y,Z, got '1,2'"),
    "viewpoint not numbers": (["--viewpoint", "a,b,c"], "expected three numbers"),
    "negative alpha": (["--alpha", "-1"], "argument --alpha"),
    "unknown method": (["--method", "fast"], "invalid choice: 'fast'"),
    "workers zero": (["-j", "0"], "argument -j/--workers"),
    "small scale": (["--scale", "5"], "at least 20"),
    "unknown field": (["--fields", "mean,colour"], "unknown field 'colour'"),
    "gamma out of range": (["--gamma", "2"], "gamma must lie in [0, 1]"),
    "output extension": (["-o", "{tmp}/out.e57"], "unknown output extension '.e57'"),
    "output directory": (["-o", "{tmp}/no/such/dir/out.ply"], "does not exist"),
    "viewpoint and input normals": (["--viewpoint", "0,0,1", "--normals-from-input"], "not allowed with argument"),
    "no input normals": (["--normals-from-input"], "has no normals"),
    "quiet and verbose": (["-q", "-v"], "--quiet and --verbose exclude each other"),
}


def test_bad_option_value_in_a_real_process(tmp_path, sphere_ply):
    out = run("compute", sphere_ply, "-o", tmp_path / "out.ply", "--viewpoint", "1,2")
    assert_one_line_error(out)
    assert "argument --viewpoint: expected three numbers X,Y,Z, got '1,2'" in out.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("case", sorted(BAD_OPTIONS))
def test_bad_options(tmp_path, sphere_ply, capsys, case):
    # in this process (argparse and option checks; the real process is tested above)
    extra, message = BAD_OPTIONS[case]
    extra = [arg.replace("{tmp}", str(tmp_path)) for arg in extra]
    args = ["compute", str(sphere_ply)] + (extra if "-o" in extra else ["-o", str(tmp_path / "out.ply")] + extra)
    status = cli.main(args)
    captured = capsys.readouterr()
    assert_one_line_error(subprocess.CompletedProcess(args, status, captured.out, captured.err))
    assert message in captured.err
    assert list(tmp_path.iterdir()) == []


def test_unexpected_errors_and_interrupts(monkeypatch, capsys, sphere_ply):
    def bug(args, log):
        raise RuntimeError("something broke\nsecond line")

    monkeypatch.setattr(cli, "_info", bug)
    assert cli.main(["info", str(sphere_ply)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("heatcurv: error: unexpected RuntimeError: something broke")
    assert "--debug" in err
    with pytest.raises(RuntimeError):
        cli.main(["info", str(sphere_ply), "--debug"])

    def interrupted(args, log):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_info", interrupted)
    assert cli.main(["info", str(sphere_ply)]) == 130
    assert "Traceback" not in capsys.readouterr().err


def test_progress_bar_runs_over_the_stages():
    from heatcurv.progress import STAGES

    stream = stdio.StringIO()
    bar = cli.StageProgress(enabled=True, stream=stream)
    for stage in STAGES:
        bar(stage, 0.0)
        bar(stage, 0.5)
        bar(stage, 1.0)
    assert bar.done == pytest.approx(100.0)
    bar.close()
    assert "principal" in stream.getvalue()
    cli.StageProgress(enabled=False)("mean", 0.5)  # does nothing


def test_warnings_are_one_line_on_stderr(monkeypatch, capsys, sphere_ply):
    import warnings

    def warns(args, log):
        warnings.warn(heatcurv.HeatcurvWarning("the area system did not converge\nafter 500 iterations"))
        warnings.warn(RuntimeWarning("invalid value in divide"))  # library noise: only with --verbose
        return 0

    monkeypatch.setattr(cli, "_info", warns)
    assert cli.main(["info", str(sphere_ply), "--quiet"]) == 0
    assert capsys.readouterr().err == "heatcurv: warning: the area system did not converge after 500 iterations\n"
