"""OBJ and OFF read as point clouds: vertices, colours, normals, errors naming the line."""

import numpy as np
import pytest

from heatcurv import HeatcurvError
from heatcurv.io import read_points


def test_obj_vertices_only(tmp_path):
    content = (
        "# mesh\nmtllib a.mtl\nv 1 2 3 1 0.5 0\nvn 0 0 1\nvt 0.5 0.5\nv 4 5 6 0 0 1\nf 1 2 1\n"
    )
    (tmp_path / "m.obj").write_text(content)
    got = read_points(tmp_path / "m.obj")
    np.testing.assert_array_equal(got.points, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(got.colours, [[255, 128, 0], [0, 0, 255]])
    (tmp_path / "p.obj").write_text("v 1 2 3\nv 4 5 6\n")
    assert read_points(tmp_path / "p.obj").colours is None


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
    assert (got.colours is None) == (colors is None) and (got.normals is None) == (normals is None)
    if colors:
        np.testing.assert_array_equal(got.colours[0], colors)
    if normals:
        np.testing.assert_array_equal(got.normals[2], normals)


@pytest.mark.parametrize(
    "name,content,message",
    [
        ("bad.obj", "v 1 2 3\nvn 0 0 1\nv 4 5\n", r"bad\.obj: line 3: expected 3 values, found 2"),
        (
            "bad.off",
            "OFF\n3 0 0\n0 0 0\n1 0 0\n",
            r"bad\.off: truncated: the header announces 3 vertices",
        ),
        ("word.off", "OFF\n2 0 0\n0 0 0\n1 x 0\n", r"word\.off: line 4: column 2 holds 'x'"),
        ("neg.off", "OFF\n-5 0 0\n0 0 0\n", r"neg\.off: line 2: the vertex count -5 is negative$"),
        (
            "huge.off",
            "OFF\n1000000000000 0 0\n0 0 0\n",
            r"huge\.off: truncated: the header announces 1000000000000 vertices, the file has 1 line after line 2$",
        ),
        ("faces.off", "OFF\n1 2 0\n0 0 0\n3 0 0 0\n", r"faces\.off: the header announces 2 faces, the file has 1 line"),
    ],
)
def test_mesh_errors_name_the_line(tmp_path, name, content, message):
    (tmp_path / name).write_text(content)
    with pytest.raises(HeatcurvError, match=message):
        read_points(tmp_path / name)


@pytest.mark.parametrize(
    "name,content,faces",
    [
        ("m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\n  f 2 4 3\n", 2),
        ("m.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n", 2),
        ("points.off", "OFF\n4 0 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n", 0),
        ("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", 0),
    ],
)
def test_mesh_faces_are_counted_and_a_warning_says_they_are_not_written(tmp_path, name, content, faces):
    import warnings

    from heatcurv import HeatcurvWarning
    from heatcurv.io import write_points

    (tmp_path / name).write_text(content)
    source = read_points(tmp_path / name)
    assert source.meta.get("faces", 0) == faces
    for ext in (".ply", ".csv"):
        out = tmp_path / f"out{ext}"
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")
            write_points(out, source.points, {"mean": np.zeros(len(source))}, source=source)
        messages = [str(w.message) for w in record if issubclass(w.category, HeatcurvWarning)]
        if faces:
            kind = name.rsplit(".", 1)[1].upper()
            assert messages == [
                f"the {faces} faces of {tmp_path / name} are not written to {out} "
                f"(heatcurv reads only the vertices of {kind} files)"
            ]
        else:
            assert messages == []


def test_off_float_colours_are_written_back_as_stored(tmp_path):
    from heatcurv.io import write_points

    (tmp_path / "c.off").write_text("COFF\n2 0 0\n0 0 0 0.1 0.2 0.3 1\n1 0 0 0.5 0.6 0.7 1\n")
    source = read_points(tmp_path / "c.off")
    write_points(tmp_path / "c.csv", source.points, source=source)
    np.testing.assert_allclose(np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1)[:, 3:6],
                               [[0.1, 0.2, 0.3], [0.5, 0.6, 0.7]], rtol=0, atol=0)


def test_mesh_readers_directly(tmp_path):
    from heatcurv.io.meshes import _read_obj, _read_off

    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    cloud = _read_obj(obj, "obj")
    np.testing.assert_array_equal(cloud.points, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    off = tmp_path / "tri.off"
    off.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    np.testing.assert_array_equal(_read_off(off, "off").points, cloud.points)
