"""The pymeshlab sample meshes read by support.scans: the counts and areas we rely on.

These are the reference values of the real-scan tests: a closed object scan
(the bunny), a range map with its camera (face000), closed models (bone, cow,
airplane) and a unit cube.
"""

import time

import numpy as np
import pytest

from support.scans import PYMESHLAB_SAMPLES, range_camera, read_mesh


def edge_use(mesh):
    """How many faces use each undirected edge, shape (edges,)."""
    f = mesh.faces
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    return np.unique(edges, axis=0, return_counts=True)[1]


def signed_volume(mesh):
    v, f = mesh.vertices, mesh.faces
    return float(np.einsum("ij,ij->", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])) / 6.0)


def test_every_sample_is_there(pymeshlab_samples):
    for name in PYMESHLAB_SAMPLES:
        assert (pymeshlab_samples / name).is_file(), name


def test_bunny_is_a_closed_scan_with_outward_file_normals(pymeshlab_samples, records):
    start = time.perf_counter()
    mesh = read_mesh(pymeshlab_samples / "bunny.obj")
    assert time.perf_counter() - start < 3.0  # 3.9 MB of OBJ: 0.4-0.7 s on the 2-core machine, by its load
    assert mesh.vertices.shape == (28088, 3) and mesh.faces.shape == (56172, 3)
    assert mesh.area == pytest.approx(0.9227, rel=1e-4)
    assert np.all(edge_use(mesh) == 2)  # closed, manifold
    assert mesh.used.all() and np.all(mesh.components() == 0)
    assert signed_volume(mesh) > 0  # faces wound outward
    assert mesh.normals is not None
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-12)
    # the file's normals against the mesh's area-weighted vertex normals (the reference of the estimates)
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", mesh.normals, mesh.vertex_normals()), -1, 1)))
    records.check("real_scans/bunny-file-normals", max_deg=angle.max(), median_deg=np.median(angle))
    assert mesh.vertex_areas().sum() == pytest.approx(mesh.area)


def test_face_range_map_faces_its_camera(pymeshlab_samples, records):
    path = pymeshlab_samples / "rangemaps" / "face000.ply"
    mesh = read_mesh(path)
    assert mesh.vertices.shape == (85849, 3) and mesh.faces.shape == (166259, 3)
    assert mesh.area == pytest.approx(19880.0, rel=1e-4)
    assert np.any(edge_use(mesh) == 1)  # a range map is open
    camera = range_camera(path)
    np.testing.assert_allclose(camera, [0.0, 0.0, 21.625208], atol=1e-5)
    used = mesh.used
    x = mesh.vertices[used]
    towards = (camera - x) / np.linalg.norm(camera - x, axis=1)[:, None]
    facing = np.einsum("ij,ij->i", mesh.vertex_normals()[used], towards)
    # the mesh's normals face the camera, seen from the front, not grazing
    records.check(
        "real_scans/face-range-map-camera", backfacing=100 * np.mean(facing <= 0),
        median_view_deg=np.degrees(np.arccos(np.median(facing))),
    )
    assert x[:, 2].max() < camera[2] - 700  # the face lies 780 to 900 units down the -z axis


@pytest.mark.parametrize("name", ["bone.ply", "cow.obj", "airplane.obj"])
def test_closed_models(pymeshlab_samples, name):
    mesh = read_mesh(pymeshlab_samples / name)
    assert mesh.area > 0 and np.all(edge_use(mesh) == 2)
    assert len(np.unique(mesh.components()[mesh.used])) == 1
    assert signed_volume(mesh) > 0


def test_cube_is_the_unit_cube(pymeshlab_samples):
    mesh = read_mesh(pymeshlab_samples / "cube.obj")
    assert mesh.vertices.shape == (8, 3) and mesh.faces.shape == (12, 3)
    assert mesh.area == pytest.approx(6.0) and signed_volume(mesh) == pytest.approx(1.0)
    assert np.all(np.einsum("ij,ij->i", mesh.vertex_normals(), mesh.vertices) > 0)  # outward from the centre


def test_every_obj_and_off_file_is_read_with_the_vertices_and_faces_read_mesh_finds(pymeshlab_samples, cgal_meshes):
    # read_points checks every face of an OBJ or OFF file against its vertices: each real file must still be read,
    # with the vertices and the number of faces (all triangles) that the independent mesh reader finds
    from heatcurv.io import read_points

    files = {path.resolve() for folder in (pymeshlab_samples, cgal_meshes) for pattern in ("*.obj", "*.off")
             for path in folder.rglob(pattern)}
    assert len(files) == 17  # 5 OBJ samples of pymeshlab, 12 CGAL models
    for path in sorted(files):
        cloud, mesh = read_points(path), read_mesh(path)
        np.testing.assert_array_equal(cloud.points, mesh.vertices, err_msg=str(path))
        assert cloud.meta["faces"] == len(mesh.faces), path
