"""File readers and writers: round trips, foreign files, every error path, atomic writes."""

import os

import laspy
import numpy as np
import plyfile
import pytest

import heatcurv.io as hio
from heatcurv import HeatcurvError, surfaces
from heatcurv.io import SUPPORTED_READ, SUPPORTED_WRITE, PointCloud, read_points, write_points

N = 300
RESULT_NAMES = "x y z nx ny nz mean gaussian k1 k2 d1x d1y d1z d2x d2y d2z area".split()


@pytest.fixture(scope="module")
def cloud():
    """Torus points far from the origin (UTM-like), with normals, colours and result-like fields."""
    sample = surfaces.Torus().sample(N, "fibonacci")
    rng = np.random.default_rng(7)
    points = sample.points + np.array([512345.25, 5.4e6, 312.5])
    fields = {
        "mean": sample.mean,
        "gaussian": sample.gaussian,
        "k1": sample.k1,
        "k2": sample.k2,
        "d1": sample.d1,
        "d2": sample.d2,
        "area": rng.random(N),
        "reliable": rng.random(N) > 0.3,
        "count": rng.integers(-1000, 1000, N),
        "weight32": rng.random(N).astype(np.float32),
    }
    colors = rng.integers(0, 256, (N, 3)).astype(np.uint8)
    return points, sample.normals, colors, fields


def expanded(fields):
    """The scalar properties a fields dict is written as."""
    out = {}
    for name, values in fields.items():
        values = np.asarray(values)
        if values.ndim == 2:
            out.update({name + axis: values[:, k] for k, axis in enumerate("xyz")})
        else:
            out[name] = values
    return out


def leftovers(directory):
    """Files in ``directory`` (temporary files are hidden: ``.name.XXXX.ext``)."""
    return sorted(os.listdir(directory))


# ----------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("ext", [".ply", ".csv", ".xyz", ".txt", ".npz"])
def test_round_trip_exact(tmp_path, cloud, ext):
    points, normals, colors, fields = cloud
    points = points.copy()
    points[5] = np.nan  # NaN rows are read faithfully, not rejected
    path = tmp_path / f"out{ext}"
    write_points(path, points, fields, normals=normals, colors=colors)
    back = read_points(path)
    assert back.format == ext[1:] and len(back) == N
    np.testing.assert_array_equal(back.points, points)
    assert back.points.dtype == np.float64
    np.testing.assert_array_equal(back.normals, normals)
    np.testing.assert_array_equal(back.colors, colors)
    assert back.colors.dtype == np.uint8
    assert list(back.fields) == list(expanded(fields))
    for name, values in expanded(fields).items():
        np.testing.assert_array_equal(back.fields[name], values, err_msg=name)
    assert leftovers(tmp_path) == [path.name]


@pytest.mark.parametrize("ext", [".las", ".laz"])
def test_round_trip_las(tmp_path, cloud, ext):
    points, normals, colors, fields = cloud
    path = tmp_path / f"out{ext}"
    write_points(path, points, fields, normals=normals, colors=colors)
    back = read_points(path)
    header = back.meta["las_header"]
    extent = np.ptp(points, axis=0).max()
    assert np.all(header.scales <= 1e-6 * extent)
    assert np.all(np.abs(back.points - points) <= header.scales)
    np.testing.assert_array_equal(back.normals, normals)
    np.testing.assert_array_equal(back.colors, colors)
    for name, values in expanded(fields).items():
        np.testing.assert_array_equal(back.fields[name], values, err_msg=name)
    assert back.fields["reliable"].dtype == np.uint8  # bools as uint8
    assert back.fields["weight32"].dtype == np.float32
    extra = list(laspy.read(path).point_format.extra_dimension_names)
    assert extra == ["nx", "ny", "nz"] + list(expanded(fields))


def test_las_source_header_dimensions_and_colours_kept(tmp_path):
    rng = np.random.default_rng(1)
    n = 200
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.001])
    header.offsets = np.array([400000.0, 5000000.0, 100.0])
    header.add_extra_dims([laspy.ExtraBytesParams("amplitude", np.float32)])
    las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(n, header=header))
    las.x = 400000.0 + rng.random(n) * 50
    las.y = 5000000.0 + rng.random(n) * 50
    las.z = 100.0 + rng.random(n)
    las.intensity = rng.integers(0, 65535, n)
    las.classification = rng.integers(0, 31, n)
    las.gps_time = rng.random(n) * 1e5
    las.amplitude = rng.random(n).astype(np.float32)
    rgb16 = rng.integers(0, 65536, (n, 3)).astype(np.uint16)
    las.red, las.green, las.blue = rgb16.T
    source_path = tmp_path / "scan.las"
    las.write(source_path)

    source = read_points(source_path)
    np.testing.assert_array_equal(source.colors, np.round(rgb16 / 257).astype(np.uint8))
    np.testing.assert_array_equal(source.fields["intensity"], las.intensity)
    mean = rng.normal(size=n)
    out = tmp_path / "result.laz"
    write_points(out, source.points, {"mean": mean}, source=source)
    written = laspy.read(out)
    assert written.point_format.id == 3 and str(written.header.version) == "1.2"
    np.testing.assert_array_equal(written.header.scales, header.scales)
    np.testing.assert_array_equal(written.header.offsets, header.offsets)
    np.testing.assert_array_equal(written.X, las.X)  # same integers: no requantisation
    np.testing.assert_array_equal(
        np.column_stack([written.red, written.green, written.blue]), rgb16
    )
    for name in ("intensity", "classification", "gps_time", "amplitude"):
        np.testing.assert_array_equal(
            np.asarray(written[name]), np.asarray(las[name]), err_msg=name
        )
    assert list(written.point_format.extra_dimension_names) == ["amplitude", "mean"]
    np.testing.assert_array_equal(written.mean, mean)


def test_las_eight_bit_values_in_sixteen_bit_colour_fields(tmp_path):
    header = laspy.LasHeader(point_format=2, version="1.2")
    las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(3, header=header))
    las.x = [0.0, 1.0, 2.0]
    las.red, las.green, las.blue = [0, 128, 255], [1, 2, 3], [255, 255, 0]
    las.write(tmp_path / "c.las")
    np.testing.assert_array_equal(read_points(tmp_path / "c.las").colors[:, 0], [0, 128, 255])


def test_las_standard_dimensions_filled_from_fields(tmp_path):
    rng = np.random.default_rng(8)
    points = rng.random((30, 3)) * 10
    fields = {
        "intensity": np.arange(30.0) * 100,
        "classification": np.full(30, 2),
        "mean": rng.random(30),
    }
    write_points(tmp_path / "a.las", points, fields, colors=np.full((30, 3), 200))
    las = laspy.read(tmp_path / "a.las")
    assert las.point_format.id == 7  # LAS 1.4 with RGB
    np.testing.assert_array_equal(las.intensity, fields["intensity"])
    np.testing.assert_array_equal(las.classification, 2)
    assert list(las.point_format.extra_dimension_names) == ["mean"]
    np.testing.assert_array_equal(las.red, 200 * 257)
    with pytest.raises(HeatcurvError, match=r"field 'intensity' does not fit the LAS dimension"):
        write_points(tmp_path / "b.las", points, {"intensity": rng.random(30)})
    with pytest.raises(HeatcurvError, match=r"longer than the 32 bytes LAS allows"):
        write_points(tmp_path / "b.las", points, {"a" * 33: rng.random(30)})
    # a LAS source without RGB gets the point format with RGB when colours are given
    header = laspy.LasHeader(point_format=1, version="1.2")
    source_las = laspy.LasData(header, points=laspy.ScaleAwarePointRecord.zeros(30, header=header))
    source_las.x = points[:, 0]
    source_las.write(tmp_path / "src.las")
    source = read_points(tmp_path / "src.las")
    write_points(tmp_path / "c.las", source.points, colors=np.full((30, 3), 9), source=source)
    assert laspy.read(tmp_path / "c.las").point_format.id == 3
    assert not (tmp_path / "b.las").exists()


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


def test_ply_property_names_for_results(tmp_path, cloud):
    points, normals, _, fields = cloud
    results = {name: fields[name] for name in ("mean", "gaussian", "k1", "k2", "d1", "d2", "area")}
    path = tmp_path / "result.ply"
    write_points(path, points, results, normals=normals)
    ply = plyfile.PlyData.read(str(path))
    assert [p.name for p in ply["vertex"].properties] == RESULT_NAMES
    assert ply.byte_order == "<" and not ply.text
    assert ply["vertex"].data.dtype["x"] == np.dtype("<f8")


# ----------------------------------------------------------------------------- foreign PLY


def _vertex_face_ply(byte_order, text, n=40):
    rng = np.random.default_rng(3)
    vertex = np.zeros(
        n,
        dtype=[
            ("x", "f4"),
            ("y", "f4"),
            ("z", "f4"),
            ("normal_x", "f4"),
            ("normal_y", "f4"),
            ("normal_z", "f4"),
            ("diffuse_red", "u1"),
            ("diffuse_green", "u1"),
            ("diffuse_blue", "u1"),
            ("quality", "f4"),
            ("label", "i4"),
        ],
    )
    for name in vertex.dtype.names:
        vertex[name] = rng.integers(0, 200, n)
    faces = np.zeros(n, dtype=[("vertex_indices", "i4", (3,))])
    faces["vertex_indices"] = rng.integers(0, n, (n, 3))
    data = plyfile.PlyData(
        [plyfile.PlyElement.describe(vertex, "vertex"), plyfile.PlyElement.describe(faces, "face")],
        text=text,
        byte_order=byte_order,
    )
    return data, vertex


@pytest.mark.parametrize(
    "byte_order,text", [(">", False), ("<", False), ("=", True)], ids=["big", "little", "ascii"]
)
def test_foreign_ply_read(tmp_path, byte_order, text):
    data, vertex = _vertex_face_ply(byte_order, text)
    path = tmp_path / "mesh.PLY"  # extension case-insensitive
    data.write(str(path))
    got = read_points(path)
    np.testing.assert_array_equal(
        got.points, np.column_stack([vertex["x"], vertex["y"], vertex["z"]])
    )
    np.testing.assert_array_equal(got.normals[:, 2], vertex["normal_z"])
    np.testing.assert_array_equal(got.colors[:, 0], vertex["diffuse_red"])
    assert list(got.fields) == ["quality", "label"]  # faces ignored
    assert got.fields["quality"].dtype == np.float32 and got.fields["quality"].dtype.isnative
    np.testing.assert_array_equal(got.fields["label"], vertex["label"])


def test_ply_with_quads_and_vertex_after_faces(tmp_path):
    vertex = np.zeros(
        5,
        dtype=[
            ("x", "f8"),
            ("y", "f8"),
            ("z", "f8"),
            ("red", "u1"),
            ("green", "u1"),
            ("blue", "u1"),
        ],
    )
    vertex["x"] = np.arange(5)
    faces = np.empty(2, dtype=[("vertex_indices", "O")])
    faces["vertex_indices"] = [np.array([0, 1, 2, 3], "i4"), np.array([1, 2, 4], "i4")]
    plyfile.PlyData(
        [plyfile.PlyElement.describe(faces, "face"), plyfile.PlyElement.describe(vertex, "vertex")]
    ).write(str(tmp_path / "q.ply"))
    got = read_points(tmp_path / "q.ply")
    np.testing.assert_array_equal(got.points[:, 0], np.arange(5))
    assert got.colors is not None and got.fields == {}


def test_ply_float_colours_are_scaled(tmp_path):
    vertex = np.zeros(
        2, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("r", "f4"), ("g", "f4"), ("b", "f4")]
    )
    vertex["r"] = [1.0, 0.5]
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex")], text=True).write(
        str(tmp_path / "f.ply")
    )
    np.testing.assert_array_equal(read_points(tmp_path / "f.ply").colors[:, 0], [255, 128])


# --------------------------------------------------------------- text, OBJ, OFF, NPY, NPZ


TEXT_CASES = {
    "plain.xyz": ("1 2 3\n4 5 6\n", None, None, []),
    "header.csv": ("X,Y,Z,Intensity\n1,2,3,7\n4,5,6,8\n", None, None, ["Intensity"]),
    "spaces.csv": ("x, y, z\n1, 2, 3\n4, 5, 6\n", None, None, []),
    "semicolon.txt": ("x;y;z;nx;ny;nz\n1;2;3;0;0;1\n4;5;6;0;1;0\n", "normals", None, []),
    "decimal_comma.txt": ("1,0;2;3\n4;5,0;6\n", None, None, []),
    "tabs.txt": (
        "x\ty\tz\tred\tgreen\tblue\n1\t2\t3\t255\t0\t9\n4\t5\t6\t0\t1\t2\n",
        None,
        "colors",
        [],
    ),
    "cc_header.txt": (
        "//X,Y,Z,R,G,B,Dist\n1,2,3,255,0,9,0.5\n4,5,6,0,1,2,0.25\n",
        None,
        "colors",
        ["Dist"],
    ),
    "hash_header.xyz": (
        "# some tool\n# x y z nx ny nz\n1 2 3 0 0 1\n4 5 6 0 1 0\n",
        "normals",
        None,
        [],
    ),
    "rgb6.xyz": ("1 2 3 255 0 9\n4 5 6 0 1 2\n", None, "colors", []),
    "normals6.xyz": ("1 2 3 0 0 1\n4 5 6 0.6 0.8 0\n", "normals", None, []),
    "unit_ints6.xyz": ("1 2 3 0 0 1\n4 5 6 0 1 0\n", "normals", None, []),
    "count.pts": ("2\n1 2 3 -120 255 0 9\n4 5 6 17 0 1 2\n", None, "colors", ["intensity"]),
    "two_scans.pts": ("1\n1 2 3 -120 255 0 9\n1\n4 5 6 17 0 1 2\n", None, "colors", ["intensity"]),
    "crlf_blank.xyz": ("1 2 3\r\n\r\n4 5 6 // trailing comment\r\n", None, None, []),
    "four.xyz": ("1 2 3 0.5\n4 5 6 0.25\n", None, None, ["column_4"]),
}


@pytest.mark.parametrize("name", list(TEXT_CASES))
def test_text_variants(tmp_path, name):
    content, normals, colors, fields = TEXT_CASES[name]
    path = tmp_path / name
    path.write_bytes(content.encode())
    got = read_points(path)
    np.testing.assert_array_equal(got.points, [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    assert (got.normals is not None) == (normals is not None)
    assert (got.colors is not None) == (colors is not None)
    if colors:
        np.testing.assert_array_equal(got.colors, [[255, 0, 9], [0, 1, 2]])
    if normals:
        np.testing.assert_array_equal(got.normals[0], [0, 0, 1])
    assert list(got.fields) == fields


def test_text_nan_rows_are_kept(tmp_path):
    (tmp_path / "nan.xyz").write_text("1 2 3\nnan 5 NaN\n7 8 9\n")
    got = read_points(tmp_path / "nan.xyz")
    assert np.isnan(got.points[1, [0, 2]]).all() and got.points[1, 1] == 5


def test_obj_vertices_only(tmp_path):
    content = (
        "# mesh\nmtllib a.mtl\nv 1 2 3 1 0.5 0\nvn 0 0 1\nvt 0.5 0.5\nv 4 5 6 0 0 1\nf 1 2 1\n"
    )
    (tmp_path / "m.obj").write_text(content)
    got = read_points(tmp_path / "m.obj")
    np.testing.assert_array_equal(got.points, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(got.colors, [[255, 128, 0], [0, 0, 255]])
    (tmp_path / "p.obj").write_text("v 1 2 3\nv 4 5 6\n")
    assert read_points(tmp_path / "p.obj").colors is None


@pytest.mark.parametrize(
    "content,colors,normals",
    [
        ("OFF\n# cube corner\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", None, None),
        (
            "COFF 3 0 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n",
            [255, 0, 0],
            None,
        ),
        ("COFF\n3 0 0\n0 0 0 1 0 0 1\n1 0 0 0 1 0 1\n0 1 0 0 0 1 1\n", [255, 0, 0], None),
        ("NOFF\n3 0 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n", None, [0, 0, 1]),
    ],
    ids=["off", "coff-bytes", "coff-floats", "noff"],
)
def test_off(tmp_path, content, colors, normals):
    (tmp_path / "m.off").write_text(content)
    got = read_points(tmp_path / "m.off")
    np.testing.assert_array_equal(got.points, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert (got.colors is None) == (colors is None) and (got.normals is None) == (normals is None)
    if colors:
        np.testing.assert_array_equal(got.colors[0], colors)
    if normals:
        np.testing.assert_array_equal(got.normals[2], normals)


def test_npy(tmp_path):
    array = np.random.default_rng(4).random((20, 6))
    np.save(tmp_path / "a.npy", array)
    got = read_points(tmp_path / "a.npy")
    np.testing.assert_array_equal(got.points, array[:, :3])
    np.testing.assert_array_equal(got.normals, array[:, 3:])
    np.save(tmp_path / "b.npy", array[:, :4])
    assert list(read_points(tmp_path / "b.npy").fields) == ["column_4"]
    np.save(tmp_path / "c.npy", array[:, :2])
    with pytest.raises(HeatcurvError, match=r"c\.npy.*shape \(20, 2\)"):
        read_points(tmp_path / "c.npy")


def test_npz_xyz_key_and_extras(tmp_path):
    rng = np.random.default_rng(5)
    np.savez(
        tmp_path / "a.npz",
        xyz=rng.random((10, 3)),
        label=np.arange(10),
        offset=np.zeros(2),
        dirs=rng.random((10, 3)),
    )
    got = read_points(tmp_path / "a.npz")
    assert list(got.fields) == ["label", "dirsx", "dirsy", "dirsz"]  # non-per-point arrays ignored
    np.savez(tmp_path / "b.npz", coords=rng.random((10, 3)))
    with pytest.raises(
        HeatcurvError, match=r"b\.npz: no 'points' or 'xyz' array \(arrays: coords\)"
    ):
        read_points(tmp_path / "b.npz")


# ----------------------------------------------------------------------------- read errors


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


def test_truncated_binary_ply(tmp_path, cloud):
    points, normals, colors, fields = cloud
    write_points(tmp_path / "full.ply", points, fields, normals=normals, colors=colors)
    data = (tmp_path / "full.ply").read_bytes()
    (tmp_path / "half.ply").write_bytes(data[: len(data) // 2])
    with pytest.raises(HeatcurvError, match=r"half\.ply: not a valid PLY file \(.*end-of-file"):
        read_points(tmp_path / "half.ply")
    data, _ = _vertex_face_ply("<", False)  # faces cut, vertices complete: still an error
    data.write(str(tmp_path / "mesh.ply"))
    raw = (tmp_path / "mesh.ply").read_bytes()
    (tmp_path / "cut.ply").write_bytes(raw[:-20])
    with pytest.raises(HeatcurvError, match=r"cut\.ply: not a valid PLY file"):
        read_points(tmp_path / "cut.ply")


def test_truncated_las(tmp_path, cloud):
    points = cloud[0]
    write_points(tmp_path / "full.las", points)
    raw = (tmp_path / "full.las").read_bytes()
    record = laspy.read(tmp_path / "full.las").header.point_format.size
    (tmp_path / "cut.las").write_bytes(raw[: -3 * record])  # whole records missing
    with pytest.raises(
        HeatcurvError, match=rf"cut\.las: truncated: the header announces {N} points"
    ):
        read_points(tmp_path / "cut.las")
    (tmp_path / "cut2.las").write_bytes(raw[:-7])
    with pytest.raises(HeatcurvError, match=r"cut2\.las: "):
        read_points(tmp_path / "cut2.las")
    write_points(tmp_path / "full.laz", points)
    (tmp_path / "cut.laz").write_bytes((tmp_path / "full.laz").read_bytes()[:-100])
    with pytest.raises(HeatcurvError, match=r"cut\.laz: not a valid LAS/LAZ file"):
        read_points(tmp_path / "cut.laz")


@pytest.mark.parametrize(
    "name,message",
    [
        ("junk.ply", r"junk\.ply: not a valid PLY file \(it does not start with 'ply'\)"),
        ("junk.las", r"junk\.las: not a valid LAS/LAZ file"),
        ("junk.laz", r"junk\.laz: not a valid LAS/LAZ file"),
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


def test_garbage_ply_header(tmp_path):
    (tmp_path / "h.ply").write_bytes(
        b"ply\nformat binary_little_endian 1.0\nelement vertex lots\nend_header\n"
    )
    with pytest.raises(HeatcurvError, match=r"h\.ply: not a valid PLY file \(line 3"):
        read_points(tmp_path / "h.ply")
    (tmp_path / "nov.ply").write_text(
        "ply\nformat ascii 1.0\nelement point 1\nproperty float x\nend_header\n1\n"
    )
    with pytest.raises(HeatcurvError, match=r"no 'vertex' element .*elements: point"):
        read_points(tmp_path / "nov.ply")


@pytest.mark.parametrize(
    "name,content,message",
    [
        ("cols.xyz", "1 2 3\n4 5 6\n7 8 9 10\n", r"cols\.xyz: line 3: expected 3 values, found 4"),
        ("short.csv", "x,y,z\n1,2,3\n\n4,5\n", r"short\.csv: line 4: expected 3 values, found 2"),
        (
            "word.txt",
            "# c\n1 2 3\n4 five 6\n",
            r"word\.txt: line 3: column 2 holds 'five', not a number",
        ),
        ("gap.csv", "x,y,z\n1,,3\n", r"gap\.csv: line 2: column 2 holds an empty value"),
        ("two.xyz", "1 2\n3 4\n", r"two\.xyz: line 1: expected at least 3 values"),
        (
            "noxyz.csv",
            "a,b,c\n1,2,3\n",
            r"noxyz\.csv: no x/y/z coordinate column \(columns: a, b, c\)",
        ),
        ("noz.csv", "x,y,h\n1,2,3\n", r"no z coordinate column"),
        (
            "hdr.csv",
            "x,y,z,w\n1,2,3\n",
            r"hdr\.csv: line 1: the header names 4 columns but line 2 has 3",
        ),
        ("bad.obj", "v 1 2 3\nvn 0 0 1\nv 4 5\n", r"bad\.obj: line 3: expected 3 values, found 2"),
        (
            "bad.off",
            "OFF\n3 0 0\n0 0 0\n1 0 0\n",
            r"bad\.off: truncated: the header announces 3 vertices",
        ),
        ("word.off", "OFF\n2 0 0\n0 0 0\n1 x 0\n", r"word\.off: line 4: column 2 holds 'x'"),
    ],
)
def test_text_errors_name_the_line(tmp_path, name, content, message):
    (tmp_path / name).write_text(content)
    with pytest.raises(HeatcurvError, match=message):
        read_points(tmp_path / name)


# --------------------------------------------------------------- write errors, atomicity


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
        (dict(colors=np.full((4, 3), 300)), r"colors must be integers 0-255"),
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


@pytest.mark.parametrize("ext", SUPPORTED_WRITE)
def test_failing_write_leaves_nothing(tmp_path, monkeypatch, cloud, ext):
    points, normals, colors, fields = cloud
    path = tmp_path / f"out{ext}"

    def broken(stream, output, target):
        stream.write(b"partial output " * 100)
        raise RuntimeError("disk on fire")

    monkeypatch.setitem(hio._WRITERS, ext, broken)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_points(path, points, fields, normals=normals)
    assert leftovers(tmp_path) == []

    # an existing output survives a failed rewrite unchanged
    path.write_bytes(b"previous result")
    with pytest.raises(RuntimeError):
        write_points(path, points, fields)
    assert leftovers(tmp_path) == [path.name] and path.read_bytes() == b"previous result"


def test_failing_library_write_leaves_nothing(tmp_path, monkeypatch, cloud):
    points = cloud[0]

    def write_then_fail(self, stream):
        stream.write(b"ply\n")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(plyfile.PlyData, "write", write_then_fail)
    with pytest.raises(HeatcurvError, match=r"cannot write .*out\.ply: No space left on device"):
        write_points(tmp_path / "out.ply", points)
    assert leftovers(tmp_path) == []
    with pytest.raises(HeatcurvError, match=r"field 'mean' has shape"):
        write_points(tmp_path / "out.las", points, {"mean": np.zeros(N - 1)})
    assert leftovers(tmp_path) == []


def test_written_file_has_ordinary_permissions(tmp_path):
    umask = os.umask(0o022)
    os.umask(umask)
    write_points(tmp_path / "out.csv", np.zeros((2, 3)))
    assert (tmp_path / "out.csv").stat().st_mode & 0o777 == 0o666 & ~umask
