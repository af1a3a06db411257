"""support.scans and .cgal: the OFF reader, the Mesh's closedness and winding, the CGAL fetch offline.

The fetch is exercised with a fake Debian package (an ``ar`` archive with the
real member layout) in place of apt-get and Debian's pool; the real download
is tested in ``tests/real/test_real_closed_meshes.py``.
"""

import hashlib
import io
import math
import subprocess
import tarfile
import zipfile

import numpy as np
import pytest

from support import cgal, scans
from support.scans import Mesh, ScanDataUnavailable, fetch_cgal_meshes, fetch_pymeshlab_samples, read_mesh

# a regular tetrahedron: faces wound outward, volume 8/3
TETRA_V = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])
TETRA_F = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])


def off_text(vertices, faces, keyword="OFF", colour="", face_colour=""):
    lines = [keyword, f"{len(vertices)} {len(faces)} 0"]
    lines += [f"{x!r} {y!r} {z!r}{colour}" for x, y, z in vertices.tolist()]
    lines += [f"3 {a} {b} {c}{face_colour}" for a, b, c in faces.tolist()]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- Mesh: edges, winding, volume


def test_tetrahedron_is_closed_wound_outward_with_its_volume():
    mesh = Mesh(TETRA_V, TETRA_F)
    edges, faces = mesh.edges()
    np.testing.assert_array_equal(edges, [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    np.testing.assert_array_equal(faces, 2)
    assert mesh.closed and mesh.consistently_wound
    assert mesh.signed_volume() == pytest.approx(8.0 / 3.0, rel=1e-14)
    np.testing.assert_allclose(mesh.outward_vertex_normals(), TETRA_V / math.sqrt(3), atol=1e-14)
    moved = Mesh(TETRA_V + [100.0, -50.0, 7.0], TETRA_F)  # the volume does not depend on the position
    assert moved.signed_volume() == pytest.approx(8.0 / 3.0, rel=1e-12)


def test_inward_winding_is_told_and_turned_outward():
    inward = Mesh(TETRA_V, TETRA_F[:, ::-1])
    assert inward.closed and inward.consistently_wound
    assert inward.signed_volume() == pytest.approx(-8.0 / 3.0, rel=1e-14)
    np.testing.assert_allclose(inward.vertex_normals(), -TETRA_V / math.sqrt(3), atol=1e-14)
    np.testing.assert_allclose(inward.outward_vertex_normals(), TETRA_V / math.sqrt(3), atol=1e-14)


def test_inconsistent_winding_and_open_meshes():
    mixed = Mesh(TETRA_V, np.vstack([TETRA_F[:3], TETRA_F[3, ::-1]]))
    assert mixed.closed and not mixed.consistently_wound
    with pytest.raises(ValueError, match="not consistently wound"):
        mixed.outward_vertex_normals()
    open_mesh = Mesh(TETRA_V, TETRA_F[:3])
    assert not open_mesh.closed and open_mesh.consistently_wound
    np.testing.assert_array_equal(open_mesh.edges()[1], [2, 2, 2, 1, 1, 1])
    flat = Mesh([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    assert flat.signed_volume() == 0.0
    with pytest.raises(ValueError, match="no volume"):
        flat.outward_vertex_normals()
    assert not Mesh(TETRA_V, np.zeros((0, 3))).closed


# --------------------------------------------------------------------------- OFF


def test_off_tetrahedron(tmp_path):
    path = tmp_path / "t.off"
    path.write_text(off_text(TETRA_V, TETRA_F))
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.vertices, TETRA_V)
    np.testing.assert_array_equal(mesh.faces, TETRA_F)
    assert mesh.normals is None and mesh.closed


def test_coff_colours_comments_and_the_counts_on_the_keyword_line(tmp_path):
    text = off_text(TETRA_V, TETRA_F, "COFF", colour=" 192 192 192 255", face_colour=" 0.5 0.5 0.5")
    text = "# a comment\n" + text.replace("COFF\n", "COFF # colours\n\n").replace("\n3 0 1 2", "\n# faces\n3 0 1 2")
    (tmp_path / "c.off").write_text(text)
    mesh = read_mesh(tmp_path / "c.off")
    np.testing.assert_array_equal(mesh.vertices, TETRA_V)
    np.testing.assert_array_equal(mesh.faces, TETRA_F)
    one_line = "OFF 4 4 0\n" + off_text(TETRA_V, TETRA_F).split("\n", 2)[2]
    (tmp_path / "o.OFF").write_text(one_line)
    np.testing.assert_array_equal(read_mesh(tmp_path / "o.OFF").faces, TETRA_F)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda t: t[: t.rindex("\n3 ") + 1], "truncated: the header announces 4 vertices and 4 faces, the file has 7"),
        (lambda t: t.replace("3 1 3 2", "4 1 3 2 0"), "face 3 is '4 1 3 2 0'; read_mesh reads OFF triangle"),
        (lambda t: t.replace("3 1 3 2", "3 1 3"), "face 3 is '3 1 3'"),
        (lambda t: t.replace("3 1 3 2", "3 1 3 4"), "refers to vertex 4, but the file has 4"),
        (lambda t: t.replace("OFF", "NOFF"), "'NOFF': an OFF variant"),
        (lambda t: t.replace("OFF", "ply"), "'ply': not an OFF file"),
        (lambda t: t.replace("4 4 0", "4 x 0"), "needs the vertex and face counts"),
        (lambda t: t.replace("4 4 0", "BINARY"), "binary OFF"),
        (lambda t: t.replace("-1.0 -1.0 1.0", "-1.0 -1.0"), "vertex 3 has 2 numbers"),
        (lambda t: t.replace("-1.0 -1.0 1.0", "-1.0 -1.0 z"), "unreadable vertex line"),
        (lambda t: "", "empty file"),
    ],
    ids=["truncated", "quad", "short-face", "index", "noff", "not-off", "counts", "binary", "short-vertex",
         "bad-number", "empty"],
)
def test_off_errors_name_the_file_and_the_problem(tmp_path, edit, message):
    path = tmp_path / "bad.off"
    path.write_text(edit(off_text(TETRA_V, TETRA_F)))
    with pytest.raises(ValueError, match="bad.off: .*" + message.replace("(", r"\(").replace(".", r"\.")):
        read_mesh(path)


# --------------------------------------------------------------------------- fetching, without apt-get


def ar_archive(members):
    out = bytearray(b"!<arch>\n")
    for name, data in members:
        out += f"{name + '/':<16}{0:<12}{0:<6}{0:<6}{100644:<8}{len(data):<10}`\n".encode()
        out += data + (b"\n" if len(data) % 2 else b"")
    return bytes(out)


def tar_bytes(files, mode):
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode=mode) as tar:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return buffer.getvalue()


def fake_deb(path, meshes=None, tree="data.tar.xz"):
    """A Debian package laid out like libcgal-demo: the models in data.tar.gz inside the file tree."""
    meshes = meshes if meshes is not None else {name: f"data of {name}\n".encode() for name in cgal.CGAL_MESHES}
    cgal_data = {"data/images/x.inr": b"an image", **{cgal._CGAL_MEMBER_PREFIX + k: v for k, v in meshes.items()},
                 "data/meshes/cube.off": b"not kept"}
    files = {"./usr/share/doc/libcgal-demo/copyright": b"c",
             "./" + cgal._DEB_DATA_TARBALL: tar_bytes(cgal_data, "w:gz")}
    compression = {"data.tar.xz": "w:xz", "data.tar.gz": "w:gz", "data.tar.zst": "w"}[tree]
    path.write_bytes(ar_archive([("debian-binary", b"2.0\n"), ("control.tar.xz", tar_bytes({}, "w:xz")),
                                 (tree, tar_bytes(files, compression))]))
    return path


@pytest.fixture
def fake_apt(tmp_path, monkeypatch):
    """Replace the download by a copy of a fake package; records the calls."""
    source = tmp_path / "source"
    source.mkdir()
    deb = fake_deb(source / cgal._DEB_NAME)
    monkeypatch.setattr(cgal, "_DEB_SHA256", hashlib.sha256(deb.read_bytes()).hexdigest())
    calls = []

    def download(dest, timeout):
        calls.append(dest)
        target = dest / deb.name
        target.write_bytes(deb.read_bytes())
        return target

    monkeypatch.setattr(cgal, "_download_deb", download)
    return calls


def test_the_scans_module_reexports_the_cgal_fetch():
    assert scans.fetch_cgal_meshes is fetch_cgal_meshes is cgal.fetch_cgal_meshes
    assert scans.CGAL_MESHES == cgal.CGAL_MESHES and len(set(cgal.CGAL_MESHES)) == 12
    assert scans._CGAL_DIRNAME == "cgal-" + cgal.CGAL_DEBIAN_VERSION.split("-")[0]
    assert scans.ScanDataUnavailable is cgal.ScanDataUnavailable


def test_fetch_extracts_the_models_atomically_and_once(tmp_path, fake_apt):
    cache = tmp_path / "cache" / "cgal"
    assert fetch_cgal_meshes(cache) == cache and len(fake_apt) == 1
    assert sorted(p.name for p in cache.iterdir()) == sorted([*cgal.CGAL_MESHES, scans._MARKER])
    for name in cgal.CGAL_MESHES:
        assert (cache / name).read_text() == f"data of {name}\n"
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["cgal"]  # no temp dir, no package left
    assert fetch_cgal_meshes(cache) == cache and len(fake_apt) == 1  # cached: no second download


def test_the_default_cache_is_next_to_the_pymeshlab_one_or_in_the_environment_one(tmp_path, monkeypatch):
    monkeypatch.delenv("HEATCURV_TEST_DATA", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cgal.cgal_cache_dir() == tmp_path / "xdg" / "heatcurv" / "test-data" / "cgal-5.5.1"
    assert cgal.cgal_cache_dir().parent == scans.default_cache_dir().parent
    monkeypatch.setenv("HEATCURV_TEST_DATA", str(tmp_path / "env"))
    assert cgal.cgal_cache_dir() == tmp_path / "env" / "cgal-5.5.1"


def test_both_caches_share_the_environment_directory_in_either_order(tmp_path, fake_apt, monkeypatch):
    wheel_dir = tmp_path / "wheel"
    wheel_dir.mkdir()
    wheel = wheel_dir / scans._WHEEL_NAME
    with zipfile.ZipFile(wheel, "w") as zf:
        for name in scans.PYMESHLAB_SAMPLES:
            zf.writestr(scans._MEMBER_PREFIX + name, name)
    monkeypatch.setattr(scans, "_WHEEL_SHA256", hashlib.sha256(wheel.read_bytes()).hexdigest())

    def download(dest, timeout):
        (dest / wheel.name).write_bytes(wheel.read_bytes())
        return dest / wheel.name

    monkeypatch.setattr(scans, "_download_wheel", download)
    for order in ("cgal first", "pymeshlab first"):
        env = tmp_path / order.replace(" ", "-")
        monkeypatch.setenv("HEATCURV_TEST_DATA", str(env))
        fetches = [fetch_cgal_meshes, fetch_pymeshlab_samples]
        for fetch in fetches if order == "cgal first" else fetches[::-1]:
            fetch()
        assert cgal._cgal_is_complete(env / "cgal-5.5.1") and scans._is_complete(env)
        assert (env / "bunny.obj").read_text() == "bunny.obj"
        assert sorted(p.name for p in env.iterdir() if p.name.startswith(".")) == [scans._MARKER]
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "cgal-5.5.1").mkdir()
    (tmp_path / "other" / "mine.txt").write_text("keep me")
    with pytest.raises(ScanDataUnavailable, match="not a complete pymeshlab sample cache"):
        fetch_pymeshlab_samples(tmp_path / "other")


def test_fetch_refuses_a_directory_of_other_files(tmp_path, fake_apt):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("keep me")
    with pytest.raises(ScanDataUnavailable, match="not a complete CGAL model cache"):
        fetch_cgal_meshes(tmp_path / "full")
    assert (tmp_path / "full" / "mine.txt").read_text() == "keep me" and not fake_apt


def test_wrong_checksum_is_refused(tmp_path, fake_apt, monkeypatch):
    monkeypatch.setattr(cgal, "_DEB_SHA256", "0" * 64)
    with pytest.raises(ScanDataUnavailable, match="SHA-256"):
        fetch_cgal_meshes(tmp_path / "c" / "cgal")
    assert list((tmp_path / "c").iterdir()) == []


def test_interrupted_fetch_leaves_nothing(tmp_path, fake_apt, monkeypatch):
    def interrupted(deb, dest):
        (dest / "camel.off").write_text("half")
        raise KeyboardInterrupt

    monkeypatch.setattr(cgal, "_extract_cgal_meshes", interrupted)
    with pytest.raises(KeyboardInterrupt):
        fetch_cgal_meshes(tmp_path / "c" / "cgal")
    assert list((tmp_path / "c").iterdir()) == []


def test_broken_packages_are_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    deb = fake_deb(tmp_path / "few.deb", meshes={"camel.off": b"x"})
    with pytest.raises(ScanDataUnavailable, match="lacks the CGAL models"):
        cgal._extract_cgal_meshes(deb, out)
    with pytest.raises(ScanDataUnavailable, match="data.tar.zst is compressed in a way Python's tarfile cannot"):
        cgal._extract_cgal_meshes(fake_deb(tmp_path / "zst.deb", tree="data.tar.zst"), out)
    (tmp_path / "bad-xz.deb").write_bytes(ar_archive([("data.tar.xz", b"\xfd7zXZ\x00 broken")]))
    with pytest.raises(ScanDataUnavailable, match="bad-xz.deb: cannot read its archives"):
        cgal._extract_cgal_meshes(tmp_path / "bad-xz.deb", out)
    (tmp_path / "x.deb").write_bytes(b"PK\x03\x04 a zip")
    with pytest.raises(ScanDataUnavailable, match="not a Debian package"):
        cgal._extract_cgal_meshes(tmp_path / "x.deb", out)
    (tmp_path / "cut.deb").write_bytes(fake_deb(tmp_path / "whole.deb").read_bytes()[:-10])
    with pytest.raises(ScanDataUnavailable, match="truncated ar member"):
        cgal._extract_cgal_meshes(tmp_path / "cut.deb", out)
    (tmp_path / "nodata.deb").write_bytes(ar_archive([("debian-binary", b"2.0\n")]))
    with pytest.raises(ScanDataUnavailable, match="no data.tar member"):
        cgal._extract_cgal_meshes(tmp_path / "nodata.deb", out)


def test_apt_get_failing_falls_back_to_the_pool(tmp_path, monkeypatch):
    deb = fake_deb(tmp_path / "pool.deb")
    seen = {}

    def apt_fails(cmd, **kwargs):
        seen["cmd"], seen["cwd"] = cmd, kwargs["cwd"]
        (kwargs["cwd"] / "partial").write_text("x")
        return subprocess.CompletedProcess(cmd, 100, "", "E: Unable to locate package libcgal-demo\n")

    def urlopen(url, timeout):
        seen["url"], seen["timeout"] = url, timeout
        return io.BytesIO(deb.read_bytes())

    monkeypatch.setattr(cgal.subprocess, "run", apt_fails)
    monkeypatch.setattr(cgal.urllib.request, "urlopen", urlopen)
    (tmp_path / "dl").mkdir()
    got = cgal._download_deb(tmp_path / "dl", 7.0)
    assert got == tmp_path / "dl" / "libcgal-demo_5.5.1-2_all.deb" and got.read_bytes() == deb.read_bytes()
    assert seen["cmd"] == ["apt-get", "download", "libcgal-demo=5.5.1-2"] and seen["cwd"] == tmp_path / "dl"
    assert seen["url"] == "http://deb.debian.org/debian/pool/main/c/cgal/libcgal-demo_5.5.1-2_all.deb"
    assert seen["timeout"] == 7.0 and sorted(p.name for p in (tmp_path / "dl").iterdir()) == [got.name]

    def no_network(url, timeout):
        raise cgal.urllib.error.URLError("Name or service not known")

    def no_apt(cmd, **kwargs):
        raise FileNotFoundError(2, "No such file", cmd[0])

    monkeypatch.setattr(cgal.urllib.request, "urlopen", no_network)
    with pytest.raises(ScanDataUnavailable, match="apt-get download failed: E: Unable.*pool.*failed too"):
        fetch_cgal_meshes(tmp_path / "c" / "cgal")
    monkeypatch.setattr(cgal.subprocess, "run", no_apt)
    with pytest.raises(ScanDataUnavailable, match="cannot run apt-get.*Name or service not known"):
        fetch_cgal_meshes(tmp_path / "c" / "cgal")
    assert list((tmp_path / "c").iterdir()) == []
