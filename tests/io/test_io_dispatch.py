"""read_points/write_points dispatch: round trips through every writable format, shared errors."""

import numpy as np
import pytest
from io_helpers import N, expanded, leftovers, make_cloud

from heatcurv import HeatcurvError
from heatcurv.io import SUPPORTED_READ, SUPPORTED_WRITE, PointCloud, read_points, write_points


@pytest.fixture(scope="module")
def cloud():
    """Torus points far from the origin (UTM-like), with normals, colours and result-like fields."""
    return make_cloud()


@pytest.mark.parametrize("ext", [".ply", ".csv", ".xyz", ".txt", ".npz"])
def test_round_trip_exact(tmp_path, cloud, ext):
    points, normals, colors, fields = cloud
    points = points.copy()
    points[5] = np.nan  # NaN rows are read faithfully, not rejected
    path = tmp_path / f"out{ext}"
    write_points(path, points, fields, normals=normals, colours=colors, dtype="float64")
    back = read_points(path)
    assert back.format == ext[1:] and len(back) == N
    np.testing.assert_array_equal(back.points, points)
    assert back.points.dtype == np.float64
    np.testing.assert_array_equal(back.normals, normals)
    np.testing.assert_array_equal(back.colours, colors)
    assert back.colours.dtype == np.uint8
    assert list(back.fields) == list(expanded(fields))
    for name, values in expanded(fields).items():
        np.testing.assert_array_equal(back.fields[name], values, err_msg=name)
    assert leftovers(tmp_path) == [path.name]


@pytest.mark.parametrize("ext", SUPPORTED_WRITE)
def test_source_fields_are_written_back(tmp_path, ext):
    points = np.random.default_rng(2).random((50, 3))
    source = PointCloud(
        points=points, fields={"intensity": np.arange(50.0), "ring": np.arange(50) % 4}
    )
    path = tmp_path / f"out{ext}"
    write_points(path, points, {"mean": np.ones(50), "ring": np.zeros(50)}, source=source)
    back = read_points(path)
    np.testing.assert_array_equal(back.fields["intensity"], np.arange(50.0))
    np.testing.assert_array_equal(back.fields["ring"], 0.0)  # the given field replaces the source's
    if ext in (".ply", ".csv", ".xyz", ".txt", ".npz"):
        assert list(back.fields) == ["intensity", "mean", "ring"]


def test_missing_file(tmp_path):
    with pytest.raises(HeatcurvError, match=r"nothere\.ply: no such file"):
        read_points(tmp_path / "nothere.ply")


def test_unknown_extensions(tmp_path):
    (tmp_path / "cloud.e57").write_bytes(b"x")
    with pytest.raises(
        HeatcurvError, match=r"cloud\.e57: unknown extension '\.e57'; supported: \.ply \.las"
    ):
        read_points(tmp_path / "cloud.e57")
    with pytest.raises(
        HeatcurvError, match=r"out\.obj: unknown extension .*\.ply \.las \.laz \.csv"
    ):
        write_points(tmp_path / "out.obj", np.zeros((3, 3)))
    assert set(SUPPORTED_WRITE) <= set(SUPPORTED_READ)


@pytest.mark.parametrize("ext", SUPPORTED_READ)
def test_empty_file(tmp_path, ext):
    path = tmp_path / f"empty{ext}"
    path.write_bytes(b"")
    with pytest.raises(HeatcurvError, match=rf"empty\{ext}: the file is empty"):
        read_points(path)


@pytest.mark.parametrize(
    "name,content,message",
    [
        ("header_only.csv", "x,y,z\n", "holds no points"),
        ("comments.xyz", "# nothing\n\n", "holds no points"),
        (
            "zero.ply",
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
            "property float z\nend_header\n",
            "holds no points",
        ),
        ("zero.off", "OFF\n0 0 0\n", "holds no points"),
        ("nov.obj", "f 1 2 3\n", r"no vertices \('v' lines\)"),
    ],
)
def test_no_points(tmp_path, name, content, message):
    (tmp_path / name).write_text(content)
    with pytest.raises(HeatcurvError, match=message):
        read_points(tmp_path / name)


@pytest.mark.parametrize(
    "name,message",
    [
        ("junk.ply", r"junk\.ply: not a valid PLY file \(it does not start with 'ply'\)"),
        ("junk.las", r"junk\.las: not a LAS/LAZ file: it starts with .*, not .LASF."),
        ("junk.laz", r"junk\.laz: not a LAS/LAZ file: it starts with .*, not .LASF."),
        ("junk.npz", r"junk\.npz: not a valid NPZ file"),
        ("junk.npy", r"junk\.npy: not a valid NPY file"),
        ("junk.xyz", r"junk\.xyz: binary data, not a text file"),
        ("junk.off", r"junk\.off: .*not an OFF file|binary data"),
    ],
)
def test_garbage_files(tmp_path, name, message):
    (tmp_path / name).write_bytes(
        bytes(np.random.default_rng(6).integers(0, 256, 4000, dtype=np.uint8))
    )
    with pytest.raises(HeatcurvError, match=message) as info:
        read_points(tmp_path / name)
    assert "\n" not in str(info.value)


def test_write_validation_errors(tmp_path):
    points = np.zeros((4, 3))
    cases = [
        (
            dict(fields={"mean": np.zeros(3)}),
            r"field 'mean' has shape \(3,\), expected \(4,\) or \(4, 3\)",
        ),
        (dict(fields={"bad name": np.zeros(4)}), r"field name 'bad name' is not usable"),
        (
            dict(fields={"nx": np.zeros(4)}, normals=np.ones((4, 3))),
            r"property 'nx', already taken",
        ),
        (dict(fields={"X": np.zeros(4)}), r"property 'X', already taken"),
        (dict(fields={"déviation": np.zeros(4)}), r"field name 'déviation' is not usable"),
        (
            dict(fields={"d1": np.zeros((4, 3)), "d1x": np.zeros(4)}),
            r"gives the property 'd1x' twice",
        ),
        (dict(fields={"label": np.array(list("abcd"))}), r"field 'label' must hold numbers"),
        (dict(normals=np.zeros((4, 2))), r"normals has shape \(4, 2\), expected \(4, 3\)"),
        (dict(colours=np.full((4, 3), 300)), r"colours must be integers 0-255"),
        (dict(source=PointCloud(points=np.zeros((5, 3)))), r"source has 5 points, points has 4"),
    ]
    for kwargs, message in cases:
        with pytest.raises(HeatcurvError, match=message):
            write_points(tmp_path / "out.ply", points, **kwargs)
    with pytest.raises(HeatcurvError, match=r"points must be numbers of shape \(n, 3\)"):
        write_points(tmp_path / "out.ply", np.zeros((4, 2)))
    with pytest.raises(HeatcurvError, match=r"LAS cannot store NaN"):
        write_points(tmp_path / "out.las", np.full((4, 3), np.nan))
    with pytest.raises(HeatcurvError, match=r"does not exist"):
        write_points(tmp_path / "missing_dir" / "out.ply", points)
    assert leftovers(tmp_path) == []


def test_colours_keyword_and_attribute(tmp_path):
    import dataclasses
    import warnings

    points = np.zeros((2, 3))
    rgb = np.array([[255, 0, 9], [0, 1, 2]], dtype=np.uint8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the British names warn about nothing
        cloud = PointCloud(points, None, rgb)
        assert cloud.colours is rgb and PointCloud(points, colours=rgb).colours is rgb
        assert "colours=True" in repr(cloud)
        assert dataclasses.replace(cloud, path=tmp_path).colours is rgb
        assert PointCloud(points).fields == {} and PointCloud(points).meta == {}
        write_points(tmp_path / "new.ply", points, colours=rgb)
    np.testing.assert_array_equal(read_points(tmp_path / "new.ply").colours, rgb)



@pytest.mark.parametrize("ext", [".ply", ".npz", ".las", ".laz", ".csv", ".txt"])
def test_computed_floats_are_float32_by_default_in_binary_formats(tmp_path, cloud, ext):
    points, normals, colors, fields = cloud
    path = tmp_path / f"out{ext}"
    write_points(path, points, fields, normals=normals, colours=colors)
    back = read_points(path)
    binary = ext in (".ply", ".npz", ".las", ".laz")
    narrow = np.float32 if binary else np.float64
    np.testing.assert_array_equal(back.normals, normals.astype(narrow))
    for name, values in expanded(fields).items():
        if values.dtype.kind == "f":
            np.testing.assert_array_equal(back.fields[name], values.astype(narrow), err_msg=name)
            if binary:
                assert back.fields[name].dtype == np.float32, name
        else:
            np.testing.assert_array_equal(back.fields[name], values, err_msg=name)
    if binary:  # integers keep an integer type: bools as 0/1 bytes (NPZ: bool), int64 as int32
        assert back.fields["reliable"].dtype in (np.uint8, np.bool_)
        assert back.fields["count"].dtype == np.int32
    # the coordinates are never narrowed
    if ext in (".las", ".laz"):
        assert np.all(np.abs(back.points - points) <= back.meta["las_header"].scales)
    else:
        np.testing.assert_array_equal(back.points, points)
    # dtype="float64" on request
    write_points(path, points, fields, normals=normals, dtype=np.float64)
    back = read_points(path)
    np.testing.assert_array_equal(back.normals, normals)
    np.testing.assert_array_equal(back.fields["mean"], fields["mean"])


def test_binary_float32_files_are_smaller(tmp_path, cloud):
    points, normals, _, fields = cloud
    for ext in (".ply", ".laz", ".npz"):
        write_points(tmp_path / f"a{ext}", points, fields, normals=normals)
        write_points(tmp_path / f"b{ext}", points, fields, normals=normals, dtype="float64")
        small, large = (tmp_path / f"a{ext}").stat().st_size, (tmp_path / f"b{ext}").stat().st_size
        assert small < 0.75 * large, (ext, small, large)


def test_bad_dtype(tmp_path):
    for dtype in ("int32", "float16", "double precision", np.complex128):
        with pytest.raises(HeatcurvError, match=r"dtype must be float32 or float64, got"):
            write_points(tmp_path / "out.ply", np.zeros((3, 3)), {"mean": np.zeros(3)}, dtype=dtype)
    assert leftovers(tmp_path) == []


def test_npz_keys_are_the_property_names(tmp_path, cloud):
    points, normals, colors, fields = cloud
    path = tmp_path / "out.npz"
    write_points(path, points, fields, normals=normals, colours=colors)
    with np.load(path) as archive:
        keys = list(archive.files)
        assert all(archive[key].shape == (N,) for key in keys if key != "points")
    # the same names as the columns of every other format (PLY, CSV, LAS extra dimensions)
    assert keys == ["points", "nx", "ny", "nz", "red", "green", "blue", *expanded(fields)]
    write_points(tmp_path / "out.csv", points, fields, normals=normals, colours=colors)
    header = (tmp_path / "out.csv").read_text().splitlines()[0].split(",")
    assert header == ["x", "y", "z", *keys[1:]]
    back = read_points(path)
    np.testing.assert_array_equal(back.colours, colors)
    np.testing.assert_array_equal(back.normals, normals.astype(np.float32))
    assert list(back.fields) == list(expanded(fields))


def test_npz_of_earlier_versions_is_still_read(tmp_path, cloud):
    points, normals, colors, fields = cloud
    # the earlier layout: normals and colours as (n, 3) arrays, (n, 3) fields as one array
    np.savez(tmp_path / "old.npz", points=points, normals=normals, colors=colors, **fields)
    old = read_points(tmp_path / "old.npz")
    write_points(tmp_path / "new.npz", points, fields, normals=normals, colours=colors, dtype="float64")
    new = read_points(tmp_path / "new.npz")
    np.testing.assert_array_equal(old.points, new.points)
    np.testing.assert_array_equal(old.normals, new.normals)
    np.testing.assert_array_equal(old.colours, new.colours)
    assert list(old.fields) == list(new.fields) == list(expanded(fields))
    for name in old.fields:
        np.testing.assert_array_equal(old.fields[name], new.fields[name], err_msg=name)
    rgb = np.array([[255, 0, 9], [0, 1, 2]], dtype=np.uint8)
    np.savez(tmp_path / "c.npz", points=np.zeros((2, 3)), colors=rgb)
    np.testing.assert_array_equal(read_points(tmp_path / "c.npz").colours, rgb)
    np.savez(tmp_path / "bad.npz", points=np.zeros((2, 3)), colors=np.full((2, 3), -1))
    with pytest.raises(HeatcurvError, match=r"'colors' \(shape \(2, 3\), dtype int64\) are not"):
        read_points(tmp_path / "bad.npz")


def test_npz_reserved_names(tmp_path):
    for name in ("points", "xyz", "normals", "colors"):
        with pytest.raises(HeatcurvError, match=rf"field name '{name}' is reserved in NPZ output"):
            write_points(tmp_path / "out.npz", np.zeros((2, 3)), {name: np.zeros(2)})
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize(
    "exc,message",
    [
        (MemoryError(), "not enough memory to read it"),
        (OverflowError("cannot fit 'int' into an index-sized integer"), "a count or value is too large"),
        (RecursionError("maximum recursion depth exceeded"), "its structure is nested too deeply to read"),
        (UnicodeDecodeError("ascii", b"\xe9", 0, 1, "ordinal not in range(128)"),
         "it holds bytes that are not valid text"),
    ],
)
def test_unforeseen_errors_are_one_plain_line(tmp_path, monkeypatch, exc, message):
    import heatcurv.io as hio

    def reader(path, fmt):
        raise exc

    monkeypatch.setitem(hio._READERS, ".xyz", reader)
    (tmp_path / "a.xyz").write_text("1 2 3\n")
    with pytest.raises(HeatcurvError) as info:
        read_points(tmp_path / "a.xyz")
    assert str(info.value).startswith(f"cannot read {tmp_path / 'a.xyz'}: {message}")
    assert "\n" not in str(info.value) and info.value.__cause__ is None
