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


# ----------------------------------------------------------------------------- files that contradict themselves

# a unit square: 4 vertices (lines 4-7), 2 triangles (lines 8-9)
SQUARE_OFF = "OFF\n# a unit square\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n"


@pytest.mark.parametrize(
    "content,faces",
    [
        (SQUARE_OFF, 2),
        ("OFF 4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n", 2),  # counts on the keyword's line
        (SQUARE_OFF.replace("4 2 0", "4 2 123"), 2),  # the edge count is ignored
        (SQUARE_OFF + "\n  \n\t\n\n", 2),  # trailing blank lines and whitespace
        (SQUARE_OFF.replace("\n", "\r\n"), 2),
        (SQUARE_OFF.replace("1 0 0\n", "1 0 0 # corner\n\n# the faces:\n"), 2),  # comments and blank lines
        (SQUARE_OFF.replace("3 0 1 2\n3 1 3 2", "3 0 1 2 255 0 0\n3 1 3 2 0 255 0"), 2),  # RGB face colours
        (SQUARE_OFF.replace("3 0 1 2\n3 1 3 2", "3 0 1 2 1.0 0.5 0 0.75\n3 1 3 2 0 0 1 1"), 2),  # RGBA floats
        (SQUARE_OFF.replace("3 0 1 2\n3 1 3 2", "3 0 1 2 7\n3 1 3 2 8"), 2),  # colour-map indices
        (SQUARE_OFF.replace("4 2 0", "4 1 0").replace("3 0 1 2\n3 1 3 2", "4 0 1 3 2"), 1),  # a quad
        (SQUARE_OFF.replace("3 1 3 2", "4 0 1 3 2 0.5 0.5 0.5"), 2),  # a triangle and a coloured quad
        (SQUARE_OFF.replace("4 2 0", "4 0 0").replace("3 0 1 2\n3 1 3 2\n", ""), 0),  # points only
        ("CNOFF\n4 2 0\n0 0 0 0 0 1 255 0 0 255\n1 0 0 0 0 1 0 255 0 255\n0 1 0 0 0 1 0 0 255 255\n"
         "1 1 0 0 0 1 9 9 9 255\n3 0 1 2\n3 1 3 2\n", 2),  # normals and colours
        ("STOFF\n4 2 0\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n1 1 0 1 1\n3 0 1 2 0.5 0.5 0.5\n3 1 3 2 1 1 1\n", 2),
    ],
    ids=["plain", "counts-on-keyword-line", "edge-count", "trailing-blanks", "crlf", "comments", "rgb",
         "rgba-floats", "colour-index", "quad", "mixed-polygons", "no-faces", "cnoff", "stoff"],
)
def test_off_files_real_writers_produce_are_read(tmp_path, content, faces):
    path = tmp_path / "m.off"
    path.write_bytes(content.encode())
    cloud = read_points(path)
    np.testing.assert_array_equal(cloud.points, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    assert cloud.meta.get("faces", 0) == faces


@pytest.mark.parametrize(
    "content,message",
    [
        # a vertex count lower than the vertex lines: the next vertex is taken for a face
        (SQUARE_OFF.replace("4 2 0", "3 2 0").replace("1 1 0", "1.5 1 0"),
         r"line 7: expected a face \('k i1 \.\.\. ik'\) after the 3 vertices the header announces, found '1\.5 1 0'$"),
        # ... unless the vertex reads as a face ('1 1 0': one corner, vertex 1, colour 0): then a line is left over
        (SQUARE_OFF.replace("4 2 0", "3 2 0"),
         r"line 9: more lines than the header announces \(3 vertices and 2 faces\)$"),
        # a duplicated vertex line: the same
        (SQUARE_OFF.replace("1 1 0\n", "1.5 1 0\n1.5 1 0\n"),
         r"line 8: expected a face \('k i1 \.\.\. ik'\) after the 4 vertices the header announces, found '1\.5 1 0'$"),
        # a vertex count higher than the vertex lines: the first face is taken for a vertex
        (SQUARE_OFF.replace("4 2 0", "5 1 0"), r"line 8: expected 3 values, found 4 \(vertex 5 of the 5 the header "
                                                r"announces\)$"),
        # a vertex line with the wrong number of coordinates
        (SQUARE_OFF.replace("1 0 0\n", "1 0\n"), r"line 5: expected 3 values, found 2 \(vertex 2 of the 4 the header "
                                                 r"announces\)$"),
        (SQUARE_OFF.replace("1 0 0\n", "1 0 0 0\n"), r"line 5: expected 3 values, found 4 \(vertex 2 of the 4"),
        (SQUARE_OFF.replace("1 0 0\n", "1 x 0\n"), r"line 5: column 2 holds 'x', not a number \(vertex 2 of the 4"),
        # a face count lower or higher than the face lines, extra lines
        (SQUARE_OFF.replace("4 2 0", "4 1 0"),
         r"line 9: more lines than the header announces \(4 vertices and 1 face\)$"),
        (SQUARE_OFF.replace("4 2 0", "4 0 0"),
         r"line 8: more lines than the header announces \(4 vertices and 0 faces\)$"),
        (SQUARE_OFF + "0 0 1\n", r"line 10: more lines than the header announces \(4 vertices and 2 faces\)$"),
        (SQUARE_OFF.replace("4 2 0", "4 3 0"),
         r"the header announces 3 faces, the file has 2 lines after its 4 vertices$"),
        # face indices out of range or not whole numbers
        (SQUARE_OFF.replace("3 1 3 2", "3 1 4 2"),
         r"line 9: face vertex index 4 is out of range \(the header announces 4 vertices, numbered 0 to 3\)$"),
        (SQUARE_OFF.replace("3 1 3 2", "3 1 -1 2"), r"line 9: face vertex index -1 is out of range"),
        (SQUARE_OFF.replace("3 1 3 2", "3 1 1.5 2"), r"line 9: face vertex index '1\.5' is not a whole number$"),
        (SQUARE_OFF.replace("3 1 3 2", "3 1 3 99999999999999999999"),
         r"line 9: face vertex index '99999999999999999999' is not a whole number$"),
        # a face's vertex count against its line
        (SQUARE_OFF.replace("3 1 3 2", "3 1 3"),
         r"line 9: the face announces 3 vertices, the line holds 2 values after it$"),
        (SQUARE_OFF.replace("3 1 3 2", "3 1 3 2 0 1"),
         r"line 9: 2 values after the face's 3 vertex indices \(a face colour is 1, 3 or 4 values\)$"),
        (SQUARE_OFF.replace("3 1 3 2", "0 1 3 2"), r"line 9: a face of 0 vertices$"),
        (SQUARE_OFF.replace("3 1 3 2", "3.0 1 3 2"), r"line 9: expected a face .* found '3\.0 1 3 2'$"),
        (SQUARE_OFF.replace("3 1 3 2", "3 1 3 2 red 0 0"), r"line 9: face colour value 'red' is not a number$"),
    ],
    ids=["vertex-count-lower", "vertex-count-lower-integral", "duplicated-vertex", "vertex-count-higher",
         "vertex-short", "vertex-long",
         "vertex-word", "face-count-lower", "face-count-zero", "extra-line", "face-count-higher", "index-high",
         "index-negative", "index-float", "index-huge", "face-short", "face-long", "face-empty", "face-k-float",
         "face-colour-word"],
)
def test_off_files_that_contradict_themselves_are_refused(tmp_path, content, message):
    path = tmp_path / "m.off"
    path.write_text(content)
    with pytest.raises(HeatcurvError, match=r"^cannot read \S+m\.off: " + message):
        read_points(path)


def test_off_mixed_polygons_are_checked_like_uniform_ones(tmp_path):
    # triangles and quads together take the token-by-token path: the same checks, the same messages
    path = tmp_path / "m.off"
    mixed = SQUARE_OFF.replace("4 2 0", "4 3 0") + "4 0 1 3 2\n"
    path.write_text(mixed)
    assert read_points(path).meta["faces"] == 3
    path.write_text(mixed.replace("4 0 1 3 2", "4 0 1 3 7"))
    with pytest.raises(HeatcurvError, match=r"line 10: face vertex index 7 is out of range"):
        read_points(path)
    path.write_text(mixed + "3 0 1 2\n")
    with pytest.raises(HeatcurvError, match=r"line 11: more lines than the header announces \(4 vertices and 3 faces"):
        read_points(path)


# lines 1-4: vertices, line 5: a normal, lines 6-7: texture coordinates
SQUARE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvt 0 0\nvt 1 1\n"


@pytest.mark.parametrize(
    "faces,count",
    [
        ("f 1 2 3\nf 2 4 3\n", 2),
        ("f 1/1 2/2 3/1\n", 1),
        ("f 1//1 2//1 3//1 # a comment\n", 1),
        ("f 1/1/1 2/2/1 4/1/1 3/2/1\n", 1),
        ("f -4 -3 -2\nf -3/-1/-1 -1/-2/-1 -2/-1/-1\n", 2),  # relative to the last 'v' line before the face
        ("g square\nusemtl red\ns 1\no thing\nl 1 2\nf 1 2 3\nvp 0.5\ncstype bspline\n", 1),  # unknown statements
    ],
    ids=["plain", "texture", "normal", "both", "negative", "other-statements"],
)
def test_obj_faces_of_every_form_are_read(tmp_path, faces, count):
    path = tmp_path / "m.obj"
    path.write_text(SQUARE_OBJ + faces)
    cloud = read_points(path)
    assert len(cloud) == 4 and cloud.meta["faces"] == count


@pytest.mark.parametrize(
    "content,message",
    [
        (SQUARE_OBJ + "f 1 2 3\nf 2 5 3\n", r"line 9: vertex index 5 is out of range: the file has 4 v lines$"),
        (SQUARE_OBJ + "f 1 2 3\nf 2/1 3/1 5/1\n", r"line 9: vertex index 5 is out of range: the file has 4 v lines$"),
        (SQUARE_OBJ + "f -5 -1 -2\n",
         r"line 8: vertex index -5 is out of range: the face follows 4 v lines$"),
        ("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n",
         r"line 3: vertex index -3 is out of range: the face follows 2 v lines$"),
        (SQUARE_OBJ + "f 0 1 2\n", r"line 8: vertex index 0 \(OBJ indices start at 1, or count back from -1\)$"),
        (SQUARE_OBJ + "f 1 2 3.5\n", r"line 8: '3\.5' is not a face corner \(a vertex index, then optionally"),
        (SQUARE_OBJ + "f 1 2 3/1/1/1\n", r"line 8: '3/1/1/1' is not a face corner"),
        (SQUARE_OBJ + "f 1 2 /1\n", r"line 8: '/1' is not a face corner"),
        (SQUARE_OBJ + "f 1 2 3\nf \n", r"line 9: a face \('f'\) with no vertices$"),
    ],
    ids=["index-high", "index-high-with-texture", "negative-too-far", "negative-before-definition", "zero",
         "float", "too-many-slashes", "no-vertex-index", "empty-face"],
)
def test_obj_faces_naming_missing_vertices_are_refused(tmp_path, content, message):
    path = tmp_path / "m.obj"
    path.write_text(content)
    with pytest.raises(HeatcurvError, match=r"^cannot read \S+m\.obj: " + message):
        read_points(path)


def test_the_fast_obj_face_parser_agrees_with_the_corner_by_corner_one():
    # uniform face blocks take a shortcut (bytes.translate and NumPy's table parser); whatever it accepts, the
    # corner-by-corner parser must accept with the same vertex indices, on random mixtures of valid and broken forms
    from pathlib import Path

    from heatcurv.io.meshes import _obj_corners, _uniform_obj_corners

    rng = np.random.default_rng(7)
    forms = ["{a}", "{a}/{b}", "{a}//{b}", "{a}/{b}/{c}", "/{a}", "{a}/", "{a}///{b}", "{a}/{b}/{c}/{d}",
             "{a}//{b}//{c}", "{a}/{b}//{c}", "//{a}", "{a}//", "-{a}//{b}", "{a}.5", "+{a}/{b}", "{a}/-{b}/{c}",
             "{a}/{b}/"]
    accepted = 0
    for _ in range(3000):
        chosen = [forms[k] for k in rng.integers(len(forms), size=3)]
        lines = []
        for _ in range(int(rng.integers(1, 4))):
            corners = [chosen[0] if rng.random() < 0.7 else chosen[int(rng.integers(1, 3))]
                       for _ in range(3 if rng.random() < 0.7 else int(rng.integers(2, 5)))]
            values = {key: int(rng.integers(1, 50)) for key in "abcd"}
            lines.append(("\t" if rng.random() < 0.2 else " ").join(c.format(**values) for c in corners))
        body = "\n".join(lines).encode()
        fast = _uniform_obj_corners(body, len(lines))
        if fast is None:
            continue
        accepted += 1
        values, faces = _obj_corners(Path("m.obj"), "", body, len(lines))
        np.testing.assert_array_equal(values, fast.ravel(), err_msg=repr(body))
        np.testing.assert_array_equal(faces, np.repeat(np.arange(len(lines)), fast.shape[1]))
    assert accepted == 232  # of the 3000 blocks, those uniform and well formed (the shortcut is taken)
