"""CGAL's closed models read by support.scans: the counts, closedness and outward normals we rely on.

These are the reference of the orientation tests and of
``benchmarks/orientation.py``: twelve animals and figures with thin parts,
whose used vertices are the cloud and whose outward vertex normals are the
truth.
"""

import os

import numpy as np
import pytest

from support.scans import CGAL_MESHES, read_mesh

# vertex and face counts of the files' headers (CGAL 5.5.1, Debian's libcgal-demo 5.5.1-2)
COUNTS = {
    "armadillo.off": (26002, 52000),
    "bear.off": (13826, 27648),
    "bull.off": (6200, 12396),
    "camel.off": (9770, 19536),
    "cow.off": (2904, 5804),
    "dino.off": (3916, 7828),
    "diplodocus.off": (23982, 47960),
    "elephant.off": (2775, 5558),
    "elk.off": (1645, 3290),
    "homer.off": (4930, 9856),
    "lion.off": (7529, 14859),
    "man.off": (17495, 34986),
}
#: the one model with holes: its boundary edges
LION_BOUNDARY_EDGES = 205


def header(path):
    """Keyword, vertex count and face count of an OFF file, read independently of read_mesh."""
    words = []
    with open(path) as fh:
        for line in fh:
            words += line.split("#", 1)[0].split()
            if len(words) >= 3:
                return words[0], int(words[1]), int(words[2])
    raise AssertionError(f"{path}: no OFF header")


def winding_number(mesh, points):
    """The winding number of the mesh's faces around each point (Van Oosterom and Strackee's solid angles)."""
    out = np.empty(len(points))
    for i, p in enumerate(points):
        a, b, c = (mesh.vertices[mesh.faces[:, k]] - p for k in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        det = np.einsum("ij,ij->i", a, np.cross(b, c))
        dot = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", a, c) * lb
        dot += np.einsum("ij,ij->i", b, c) * la
        out[i] = np.arctan2(det, dot).sum() / (2.0 * np.pi)
    return out


def test_the_fetch_gives_the_twelve_models(cgal_meshes):
    assert sorted(COUNTS) == sorted(CGAL_MESHES)
    files = sorted(p.name for p in cgal_meshes.iterdir() if not p.name.startswith("."))
    assert files == sorted(CGAL_MESHES)
    assert sum(os.path.getsize(cgal_meshes / name) for name in CGAL_MESHES) == 7907512


@pytest.mark.parametrize("name", CGAL_MESHES)
def test_model_is_read_with_its_header_counts_closed_and_wound_outward(cgal_meshes, name):
    path = cgal_meshes / name
    keyword, n_vertices, n_faces = header(path)
    assert (n_vertices, n_faces) == COUNTS[name]
    assert keyword == ("COFF" if name == "dino.off" else "OFF")  # dino's vertices carry colours
    mesh = read_mesh(path)
    assert mesh.vertices.shape == (n_vertices, 3) and mesh.faces.shape == (n_faces, 3)
    assert mesh.normals is None and np.isfinite(mesh.vertices).all()
    assert mesh.used.all() and np.all(mesh.components() == 0)
    assert mesh.consistently_wound
    _, faces_per_edge = mesh.edges()
    if name == "lion.off":
        assert not mesh.closed
        assert np.count_nonzero(faces_per_edge == 1) == LION_BOUNDARY_EDGES
        assert np.all((faces_per_edge == 1) | (faces_per_edge == 2))
    else:
        assert mesh.closed and np.all(faces_per_edge == 2)  # every edge in two faces
    # outward: positive signed volume, so the winding's vertex normals point out
    volume = mesh.signed_volume()
    assert volume > 0
    normals = mesh.vertex_normals()
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    np.testing.assert_array_equal(mesh.outward_vertex_normals(), normals)
    # outward vertex by vertex: stepping against the normal the winding number rises by one. Measured on 100
    # random vertices: all 100 but 1 on bull and man (both sides outside: a sheet of no thickness or a crease
    # the averaged normal lies along) and 2 on lion (0.47: beside its holes)
    index = np.random.default_rng(0).choice(n_vertices, 100, replace=False)
    edges, _ = mesh.edges()
    step = 1e-3 * np.median(np.linalg.norm(np.diff(mesh.vertices[edges], axis=1)[:, 0], axis=1))
    x, n = mesh.vertices[index], normals[index]
    jump = winding_number(mesh, x - step * n) - winding_number(mesh, x + step * n)
    assert np.count_nonzero(np.abs(jump - 1.0) < 0.1) >= 97


def test_a_truncated_model_is_refused_clearly(cgal_meshes, tmp_path):
    data = (cgal_meshes / "camel.off").read_bytes()
    cut = tmp_path / "camel.off"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match=r"camel\.off: truncated: the header announces 9770 vertices and 19536 faces"):
        read_mesh(cut)
