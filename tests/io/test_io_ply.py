"""PLY: property names written, foreign files (byte orders, ascii, faces, quads), PLY errors."""

import numpy as np
import plyfile
import pytest
from io_helpers import make_cloud

from heatcurv import HeatcurvError
from heatcurv.io import read_points, write_points

RESULT_NAMES = "x y z nx ny nz mean gaussian k1 k2 d1x d1y d1z d2x d2y d2z area".split()


@pytest.fixture(scope="module")
def cloud():
    """Torus points far from the origin (UTM-like), with normals, colours and result-like fields."""
    return make_cloud()


def test_ply_property_names_for_results(tmp_path, cloud):
    points, normals, _, fields = cloud
    results = {name: fields[name] for name in ("mean", "gaussian", "k1", "k2", "d1", "d2", "area")}
    path = tmp_path / "result.ply"
    write_points(path, points, results, normals=normals)
    ply = plyfile.PlyData.read(str(path))
    assert [p.name for p in ply["vertex"].properties] == RESULT_NAMES
    assert ply.byte_order == "<" and not ply.text
    assert ply["vertex"].data.dtype["x"] == np.dtype("<f8")


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
    np.testing.assert_array_equal(got.colours[:, 0], vertex["diffuse_red"])
    assert list(got.fields) == ["quality", "label"]  # faces ignored
    assert got.fields["quality"].dtype == np.float32 and got.fields["quality"].dtype.isnative
    np.testing.assert_array_equal(got.fields["label"], vertex["label"])


@pytest.mark.parametrize("byte_order,text", [(">", False), ("=", True)], ids=["big", "ascii"])
def test_ply_mesh_written_back_with_faces_and_every_property(tmp_path, byte_order, text):
    data, vertex = _vertex_face_ply(byte_order, text)
    data.comments = ["scanned by someone"]
    data.obj_info = ["units mm"]
    data.write(str(tmp_path / "mesh.ply"))
    source = read_points(tmp_path / "mesh.ply")
    assert source.meta["faces"] == 40
    mean = np.linspace(-1, 1, 40)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # faces kept: nothing to warn about
        write_points(tmp_path / "out.ply", source.points, {"mean": mean}, source=source)
    out = plyfile.PlyData.read(str(tmp_path / "out.ply"))
    assert [element.name for element in out.elements] == ["vertex", "face"]
    np.testing.assert_array_equal(
        np.vstack(out["face"].data["vertex_indices"]), np.vstack(data["face"].data["vertex_indices"])
    )
    assert out.comments == ["scanned by someone", "written by heatcurv"] and out.obj_info == ["units mm"]
    written = out["vertex"].data
    # every input property, with its stored type: float coordinates and normals stay float
    for name, kind in [("x", "f4"), ("nx", "f4"), ("red", "u1"), ("quality", "f4"), ("label", "i4"),
                       ("mean", "f4")]:
        assert written.dtype[name] == np.dtype("<" + kind), name
    for name, stored in [("x", "x"), ("nz", "normal_z"), ("blue", "diffuse_blue"), ("quality", "quality"),
                         ("label", "label")]:
        np.testing.assert_array_equal(written[name], vertex[stored], err_msg=name)
    # the output read again gives the same cloud and faces
    again = read_points(tmp_path / "out.ply")
    assert again.meta["faces"] == 40 and list(again.fields) == ["quality", "label", "mean"]


def test_ply_coordinates_keep_their_type_and_are_never_narrowed(tmp_path):
    rng = np.random.default_rng(12)
    points = rng.random((20, 3)) + 1000.0
    write_points(tmp_path / "f8.ply", points)
    assert plyfile.PlyData.read(str(tmp_path / "f8.ply"))["vertex"].data.dtype["x"] == np.dtype("<f8")
    write_points(tmp_path / "f4.ply", points.astype(np.float32))  # float32 points: float32 coordinates
    source = read_points(tmp_path / "f4.ply")
    assert source.meta["points_dtype"] == np.float32
    write_points(tmp_path / "again.ply", source.points, {"mean": np.ones(20)}, source=source)
    assert plyfile.PlyData.read(str(tmp_path / "again.ply"))["vertex"].data.dtype["x"] == np.dtype("<f4")
    moved = source.points + 1e-4  # no longer float32 values: written as double, exactly
    write_points(tmp_path / "moved.ply", moved, source=source)
    np.testing.assert_array_equal(read_points(tmp_path / "moved.ply").points, moved)


def test_ply_sixteen_bit_colours_are_kept(tmp_path):
    vertex = np.zeros(3, dtype=[("x", "f8"), ("y", "f8"), ("z", "f8"), ("red", "u2"), ("green", "u2"),
                                ("blue", "u2")])
    vertex["red"] = [0, 1000, 65535]
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex")]).write(str(tmp_path / "c16.ply"))
    source = read_points(tmp_path / "c16.ply")
    np.testing.assert_array_equal(source.colours[:, 0], [0, 4, 255])
    write_points(tmp_path / "out.ply", source.points, source=source)
    written = plyfile.PlyData.read(str(tmp_path / "out.ply"))["vertex"].data
    assert written.dtype["red"] == np.dtype("<u2")
    np.testing.assert_array_equal(written["red"], [0, 1000, 65535])
    write_points(tmp_path / "out.las", source.points, source=source)  # LAS colours are 16-bit too
    import laspy

    np.testing.assert_array_equal(laspy.read(tmp_path / "out.las").red, [0, 1000, 65535])


def test_ply_faces_not_writable_elsewhere_give_one_warning(tmp_path):
    from heatcurv import HeatcurvWarning

    data, _ = _vertex_face_ply("<", False)
    data.write(str(tmp_path / "mesh.ply"))
    source = read_points(tmp_path / "mesh.ply")
    for ext in (".las", ".csv", ".npz"):
        out = tmp_path / f"out{ext}"
        with pytest.warns(HeatcurvWarning) as record:
            write_points(out, source.points, source=source)
        assert len(record) == 1
        message = str(record[0].message)
        assert message == (
            f"the 40 faces of {tmp_path / 'mesh.ply'} are not written to {out} "
            f"({ext} holds points only; write a .ply to keep them)"
        )
        assert record[0].filename == __file__  # points at the caller
        assert out.exists()


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
    assert got.colours is not None and got.fields == {}


def test_ply_float_colours_are_scaled(tmp_path):
    vertex = np.zeros(
        2, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("r", "f4"), ("g", "f4"), ("b", "f4")]
    )
    vertex["r"] = [1.0, 0.5]
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex")], text=True).write(
        str(tmp_path / "f.ply")
    )
    np.testing.assert_array_equal(read_points(tmp_path / "f.ply").colours[:, 0], [255, 128])


def test_truncated_binary_ply(tmp_path, cloud):
    points, normals, colors, fields = cloud
    write_points(tmp_path / "full.ply", points, fields, normals=normals, colours=colors)
    data = (tmp_path / "full.ply").read_bytes()
    (tmp_path / "half.ply").write_bytes(data[: len(data) // 2])
    header = data.index(b"end_header\n") + len(b"end_header\n")
    record = (len(data) - header) // 300
    with pytest.raises(
        HeatcurvError,
        match=rf"half\.ply: the header announces 300 vertices of {record} bytes \({300 * record} bytes\) "
        rf"after the header, the file holds {len(data) // 2 - header}$",
    ):
        read_points(tmp_path / "half.ply")
    data, _ = _vertex_face_ply("<", False)  # faces cut, vertices complete: still an error
    data.write(str(tmp_path / "mesh.ply"))
    raw = (tmp_path / "mesh.ply").read_bytes()
    (tmp_path / "cut.ply").write_bytes(raw[:-20])
    with pytest.raises(HeatcurvError, match=r"cut\.ply: not a valid PLY file"):
        read_points(tmp_path / "cut.ply")


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
