"""support.scans: the mesh reader on small files written here, and the fetch without a network.

The fetch is exercised with a fake wheel (a zip with the real member layout)
in place of pip; the real download is tested in ``tests/real``.
"""

import hashlib
import math
import subprocess
import zipfile

import numpy as np
import pytest

from support import scans
from support.scans import Mesh, ScanDataUnavailable, fetch_pymeshlab_samples, range_camera, read_mesh

# a regular tetrahedron: edge 2 sqrt(2), faces wound outward
TETRA_V = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])
TETRA_F = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
TETRA_AREA = 4 * math.sqrt(3) / 4 * 8.0  # four equilateral triangles of side 2 sqrt(2)

CUBE_OBJ = """# unit cube [0, 1]^3 as quads, outward
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
"""


def write(path, text):
    path.write_text(text)
    return path


def obj_text(vertices, faces, corner=lambda i: str(i + 1)):
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += ["f " + " ".join(corner(int(i)) for i in f) for f in faces]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- Mesh


def test_tetrahedron_area_vertex_areas_normals():
    mesh = Mesh(TETRA_V, TETRA_F)
    assert mesh.area == pytest.approx(TETRA_AREA, rel=1e-14)
    np.testing.assert_allclose(mesh.face_areas(), TETRA_AREA / 4, rtol=1e-14)
    np.testing.assert_allclose(mesh.vertex_areas(), TETRA_AREA / 4, rtol=1e-14)  # 3 faces x 1/3 each
    # outward: along the vertex's position vector (the centroid is the origin)
    np.testing.assert_allclose(mesh.vertex_normals(), TETRA_V / math.sqrt(3), atol=1e-14)
    assert mesh.used.all() and len(mesh) == 4
    np.testing.assert_array_equal(mesh.components(), 0)


def test_unused_vertex_and_two_components():
    v = np.vstack([TETRA_V, TETRA_V + 10.0, [[50.0, 50.0, 50.0]]])
    f = np.vstack([TETRA_F, TETRA_F + 4])
    mesh = Mesh(v, f)
    np.testing.assert_array_equal(mesh.used, [True] * 8 + [False])
    assert mesh.vertex_areas()[8] == 0.0 and mesh.vertex_areas().sum() == pytest.approx(mesh.area)
    np.testing.assert_array_equal(mesh.vertex_normals()[8], 0.0)
    labels = mesh.components()
    assert labels.dtype == np.int64 and len(np.unique(labels)) == 3
    assert len(set(labels[:4])) == 1 and len(set(labels[4:8])) == 1 and labels[0] != labels[4] != labels[8]


def test_mesh_checks_its_arrays():
    with pytest.raises(ValueError, match="face indices"):
        Mesh(TETRA_V, [[0, 1, 4]])
    with pytest.raises(ValueError, match="vertices"):
        Mesh(TETRA_V[:, :2], TETRA_F)
    with pytest.raises(ValueError, match="normals"):
        Mesh(TETRA_V, TETRA_F, normals=np.ones((3, 3)))
    mesh = Mesh(TETRA_V.tolist(), TETRA_F.tolist())
    assert mesh.vertices.dtype == np.float64 and mesh.faces.dtype == np.int64


def test_fan_triangulation_of_mixed_polygons():
    corners = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11])  # triangle, pentagon, quad
    tri = scans._fan(corners, np.array([3, 5, 4]))
    expected = [[0, 1, 2], [3, 4, 5], [3, 5, 6], [3, 6, 7], [8, 9, 10], [8, 10, 11]]
    np.testing.assert_array_equal(tri, expected)


# --------------------------------------------------------------------------- OBJ


def test_obj_tetrahedron(tmp_path):
    mesh = read_mesh(write(tmp_path / "t.obj", obj_text(TETRA_V, TETRA_F)))
    np.testing.assert_array_equal(mesh.vertices, TETRA_V)
    np.testing.assert_array_equal(mesh.faces, TETRA_F)
    assert mesh.normals is None
    assert mesh.area == pytest.approx(TETRA_AREA)


def test_obj_quads_fan_triangulated(tmp_path):
    mesh = read_mesh(write(tmp_path / "cube.obj", CUBE_OBJ))
    assert mesh.faces.shape == (12, 3) and mesh.area == pytest.approx(6.0)
    centre_out = np.einsum("ij,ij->i", mesh.vertex_normals(), mesh.vertices - 0.5)
    assert np.all(centre_out > 0)  # quads wound outward stay outward
    signed = np.einsum("ij,ij->", mesh.vertices[mesh.faces[:, 0]],
                       np.cross(mesh.vertices[mesh.faces[:, 1]], mesh.vertices[mesh.faces[:, 2]])) / 6
    assert signed == pytest.approx(1.0)  # the cube's volume, positive: outward


def test_obj_negative_indices_are_relative_to_the_vertices_so_far(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -4 -3 -1\nf 1 -1 2\n"
    mesh = read_mesh(write(tmp_path / "neg.obj", text))
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 1, 3], [0, 3, 1]])


@pytest.mark.parametrize(
    "corner",
    [lambda i: f"{i + 1}//{i + 1}", lambda i: f"{i + 1}/{i + 1}/{i + 1}", lambda i: f"{i + 1}/7"],
    ids=["v//vn", "v/vt/vn", "v/vt"],
)
def test_obj_corner_forms_and_file_normals(tmp_path, corner):
    text = obj_text(TETRA_V, TETRA_F, corner)
    normals = TETRA_V * 5.0  # not unit in the file
    text += "".join(f"vn {x} {y} {z}\n" for x, y, z in normals)
    mesh = read_mesh(write(tmp_path / "t.obj", text))
    np.testing.assert_array_equal(mesh.faces, TETRA_F)
    if "/7" in corner(0):
        assert mesh.normals is None
    else:
        np.testing.assert_allclose(mesh.normals, TETRA_V / math.sqrt(3), atol=1e-15)


def test_obj_mixed_corner_forms_and_negative_normals(tmp_path):
    text = (
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
        "vn 0 0 -1\nvn 0 -2 0\n"
        "f 1//1 3//-2 2//1\n"
        "f 1/5/-1 2/5/2 4/1/2\n"
        "vt 0 0\n"
    )
    mesh = read_mesh(write(tmp_path / "m.obj", text))
    np.testing.assert_array_equal(mesh.faces, [[0, 2, 1], [0, 1, 3]])
    # vertex 0 and 1 average (0, 0, -1) and (0, -1, 0); 2 is (0, 0, -1); 3 is (0, -1, 0)
    s = 1 / math.sqrt(2)
    np.testing.assert_allclose(mesh.normals, [[0, -s, -s], [0, -s, -s], [0, 0, -1], [0, -1, 0]], atol=1e-15)


def test_obj_vertex_without_normal_gets_nan(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nvn 0 0 1\nf 1//1 2//1 3//1\n"
    mesh = read_mesh(write(tmp_path / "m.obj", text))
    np.testing.assert_allclose(mesh.normals[:3], [[0, 0, 1]] * 3)
    assert np.all(np.isnan(mesh.normals[3]))


def test_obj_comments_indentation_crlf_and_extra_columns(tmp_path):
    text = "# c\r\n  v 0 0 0 1.0\r\nv 1 0 0 0.5 0.5 0.5\r\n\tv 0 1 0\r\nf 1 2 3 # a comment\r\no x\r\ns off\r\n"
    mesh = read_mesh(write(tmp_path / "m.obj", text))
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2]])


@pytest.mark.parametrize(
    "text, match",
    [
        ("f 1 2 3\n", "no vertices"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "vertex 4"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "index 0"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "fewer than 3"),
        ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", "fewer than 3 numbers"),
        ("v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n", "unreadable"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 q\n", "unreadable"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", "vertex -4"),
    ],
)
def test_obj_errors_name_the_file(tmp_path, text, match):
    path = write(tmp_path / "bad.obj", text)
    with pytest.raises(ValueError, match=match) as info:
        read_mesh(path)
    assert "bad.obj" in str(info.value)


def test_unknown_extension(tmp_path):
    with pytest.raises(ValueError, match=r"\.obj, \.ply and \.off files, not \.stl"):
        read_mesh(write(tmp_path / "x.stl", "solid x\n"))


# --------------------------------------------------------------------------- PLY


def ply_header(fmt, nv, nf, face_prop="vertex_indices", normals=False, camera=False):
    lines = ["ply", f"format {fmt} 1.0"]
    if camera:
        lines += ["element camera 1"] + [f"property float {p}" for p in ("view_px", "view_py", "view_pz")]
        lines += ["property float focal"]
    lines += [f"element vertex {nv}", "property float x", "property float y", "property float z"]
    if normals:
        lines += ["property float nx", "property float ny", "property float nz"]
    lines += [f"element face {nf}", f"property list uchar int {face_prop}", "end_header"]
    return "\n".join(lines) + "\n"


def test_ascii_ply_quads_and_normals(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    body = "".join(f"{x} {y} {z} 0 0 2\n" for x, y, z in v) + "4 0 1 2 3\n"
    path = write(tmp_path / "q.ply", ply_header("ascii", 4, 1, normals=True) + body)
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_allclose(mesh.normals, [[0, 0, 1]] * 4)
    np.testing.assert_allclose(mesh.vertex_normals(), [[0, 0, 1]] * 4)
    assert mesh.area == pytest.approx(1.0)


@pytest.mark.parametrize("face_prop", ["vertex_indices", "vertex_index"])
@pytest.mark.parametrize("quads", [False, True], ids=["triangles", "polygons"])
def test_binary_ply_with_camera(tmp_path, face_prop, quads):
    header = ply_header("binary_little_endian", 4, 2 if quads else 4, face_prop=face_prop, camera=True)
    cam = np.array([(0.5, -1.0, 21.5, 14.0)], dtype="<f4").tobytes()
    verts = TETRA_V.astype("<f4").tobytes()
    if quads:  # a triangle and a quad (the tetrahedron's two faces and a degenerate closure)
        faces = bytes([3]) + np.array([0, 1, 2], "<i4").tobytes() + bytes([4]) + np.array([0, 3, 1, 2], "<i4").tobytes()
    else:
        faces = b"".join(bytes([3]) + np.array(f, "<i4").tobytes() for f in TETRA_F)
    path = tmp_path / "b.ply"
    path.write_bytes(header.encode() + cam + verts + faces)
    mesh = read_mesh(path)
    np.testing.assert_allclose(mesh.vertices, TETRA_V)
    if quads:
        np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 3, 1], [0, 1, 2]])
    else:
        np.testing.assert_array_equal(mesh.faces, TETRA_F)
        assert mesh.area == pytest.approx(TETRA_AREA, rel=1e-6)
    np.testing.assert_allclose(range_camera(path), [0.5, -1.0, 21.5])


def test_ply_errors(tmp_path):
    path = write(tmp_path / "nof.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                 "property float y\nproperty float z\nend_header\n0 0 0\n")
    mesh = read_mesh(path)  # a point cloud: no faces
    assert mesh.faces.shape == (0, 3) and mesh.area == 0.0
    with pytest.raises(ValueError, match="camera"):
        range_camera(path)
    bad = write(tmp_path / "bad.ply", ply_header("ascii", 3, 1, face_prop="corners") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    with pytest.raises(ValueError, match="vertex_indices"):
        read_mesh(bad)


# --------------------------------------------------------------------------- fetching, without pip


def fake_wheel(directory, files=None, junk=True):
    """A zip laid out like the pymeshlab wheel: the samples under the data prefix, plus other members."""
    files = files if files is not None else {name: f"data of {name}\n" for name in scans.PYMESHLAB_SAMPLES}
    wheel = directory / scans._WHEEL_NAME
    with zipfile.ZipFile(wheel, "w") as zf:
        if junk:
            zf.writestr("pymeshlab/__init__.py", "")
            zf.writestr(f"pymeshlab-{scans.PYMESHLAB_VERSION}.data/purelib/pymeshlab/tests/test_x.py", "")
        for name, text in files.items():
            zf.writestr(scans._MEMBER_PREFIX + name, text)
        zf.writestr(scans._MEMBER_PREFIX + "rangemaps/", "")  # a directory entry
    return wheel


@pytest.fixture
def fake_pip(tmp_path, monkeypatch):
    """Replace the download by a copy of a fake wheel; records the calls and the wheel's path."""
    source = tmp_path / "source"
    source.mkdir()
    wheel = fake_wheel(source)
    monkeypatch.setattr(scans, "_WHEEL_SHA256", hashlib.sha256(wheel.read_bytes()).hexdigest())
    calls = []

    def download(dest, timeout):
        calls.append(dest)
        target = dest / wheel.name
        target.write_bytes(wheel.read_bytes())
        return target

    monkeypatch.setattr(scans, "_download_wheel", download)
    return calls


def test_fetch_extracts_the_samples_atomically_and_once(tmp_path, fake_pip):
    cache = tmp_path / "cache" / "pml"
    out = fetch_pymeshlab_samples(cache)
    assert out == cache and len(fake_pip) == 1
    for name in scans.PYMESHLAB_SAMPLES:
        assert (cache / name).read_text() == f"data of {name}\n"
    assert not (cache / "__init__.py").exists() and not (cache / "test_x.py").exists()
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["pml"]  # no temp dir, no wheel left
    assert not list(cache.rglob("*.whl"))
    assert fetch_pymeshlab_samples(cache) == cache and len(fake_pip) == 1  # cached: no second download


def test_fetch_uses_the_environment_cache(tmp_path, fake_pip, monkeypatch):
    monkeypatch.setenv("HEATCURV_TEST_DATA", str(tmp_path / "env"))
    assert scans.default_cache_dir() == tmp_path / "env"
    assert fetch_pymeshlab_samples() == tmp_path / "env"
    monkeypatch.delenv("HEATCURV_TEST_DATA")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert scans.default_cache_dir() == tmp_path / "xdg" / "heatcurv" / "test-data" / "pymeshlab-2025.7.post1"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert scans.default_cache_dir() == tmp_path / "home" / ".cache" / "heatcurv" / "test-data" / (
        "pymeshlab-2025.7.post1"
    )


def test_fetch_into_an_existing_empty_directory(tmp_path, fake_pip):
    (tmp_path / "empty").mkdir()
    assert (fetch_pymeshlab_samples(tmp_path / "empty") / "bunny.obj").is_file()


def test_fetch_refuses_a_directory_of_other_files(tmp_path, fake_pip):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("keep me")
    with pytest.raises(ScanDataUnavailable, match="not a complete"):
        fetch_pymeshlab_samples(tmp_path / "full")
    assert (tmp_path / "full" / "mine.txt").read_text() == "keep me" and not fake_pip


def test_interrupted_fetch_leaves_nothing(tmp_path, fake_pip, monkeypatch):
    def interrupted(wheel, dest):
        (dest / "bunny.obj").write_text("half")
        raise KeyboardInterrupt

    monkeypatch.setattr(scans, "_extract_samples", interrupted)
    with pytest.raises(KeyboardInterrupt):
        fetch_pymeshlab_samples(tmp_path / "c" / "pml")
    assert list((tmp_path / "c").iterdir()) == []


def test_wrong_checksum_is_refused(tmp_path, fake_pip, monkeypatch):
    monkeypatch.setattr(scans, "_WHEEL_SHA256", "0" * 64)
    with pytest.raises(ScanDataUnavailable, match="SHA-256"):
        fetch_pymeshlab_samples(tmp_path / "c" / "pml")
    assert list((tmp_path / "c").iterdir()) == []


def test_wheel_without_the_samples_is_refused(tmp_path):
    wheel = fake_wheel(tmp_path, files={"bunny.obj": "x"})
    (tmp_path / "out").mkdir()
    with pytest.raises(ScanDataUnavailable, match="lacks the sample meshes"):
        scans._extract_samples(wheel, tmp_path / "out")
    (tmp_path / "bad.whl").write_bytes(b"not a zip")
    with pytest.raises(ScanDataUnavailable, match="not a valid wheel"):
        scans._extract_samples(tmp_path / "bad.whl", tmp_path / "out")


def test_unsafe_member_paths_are_refused(tmp_path):
    wheel = tmp_path / "evil.whl"
    with zipfile.ZipFile(wheel, "w") as zf:
        zf.writestr(scans._MEMBER_PREFIX + "../../escape.txt", "x")
    (tmp_path / "out").mkdir()
    with pytest.raises(ScanDataUnavailable, match="unsafe"):
        scans._extract_samples(wheel, tmp_path / "out")
    assert not (tmp_path / "escape.txt").exists()


def test_pip_failure_and_timeout_are_reported(tmp_path, monkeypatch):
    seen = {}

    def failing(cmd, **kwargs):
        seen["cmd"], seen["kwargs"] = cmd, kwargs
        return subprocess.CompletedProcess(cmd, 1, "", "WARNING: retrying\nERROR: No matching distribution found\n")

    monkeypatch.setattr(scans.subprocess, "run", failing)
    with pytest.raises(ScanDataUnavailable, match="failed: .*No matching distribution found"):
        fetch_pymeshlab_samples(tmp_path / "c" / "pml")
    cmd = seen["cmd"]
    assert cmd[1:4] == ["-m", "pip", "download"] and "pymeshlab==2025.7.post1" in cmd and "--no-deps" in cmd
    assert seen["kwargs"]["timeout"] == 300.0
    assert list((tmp_path / "c").iterdir()) == []

    def slow(cmd, **kwargs):
        raise subprocess.TimeoutExpired(cmd, kwargs["timeout"])

    monkeypatch.setattr(scans.subprocess, "run", slow)
    with pytest.raises(ScanDataUnavailable, match="timed out after 5 s"):
        fetch_pymeshlab_samples(tmp_path / "c" / "pml", timeout=5)

    def missing(cmd, **kwargs):
        raise FileNotFoundError(2, "No such file", cmd[0])

    monkeypatch.setattr(scans.subprocess, "run", missing)
    with pytest.raises(ScanDataUnavailable, match="cannot run pip"):
        fetch_pymeshlab_samples(tmp_path / "c" / "pml")


def test_pip_success_without_the_wheel_is_reported(tmp_path, monkeypatch):
    monkeypatch.setattr(scans.subprocess, "run", lambda cmd, **kw: subprocess.CompletedProcess(cmd, 0, "", ""))
    with pytest.raises(ScanDataUnavailable, match="did not produce"):
        fetch_pymeshlab_samples(tmp_path / "c" / "pml")


def test_an_unwritable_cache_is_reported(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache's parent should be")
    with pytest.raises(ScanDataUnavailable):
        fetch_pymeshlab_samples(blocker / "pml")
