"""Geodesic distance on a real scan: bunny.obj's vertices against exact geodesics on its mesh.

The exact distance is the polyhedral geodesic on the mesh itself (pygeodesic's
Mitchell-Mount-Papadimitriou algorithm), from the top of an ear, a foot and the
back; heatcurv sees the vertices only. Errors are mean relative errors in %.
"""

import numpy as np
import pygeodesic.geodesic as geodesic

import heatcurv
from support.scans import read_mesh


def test_bunny_vertices_against_the_mesh_geodesics(pymeshlab_samples, records):
    mesh = read_mesh(pymeshlab_samples / "bunny.obj")
    vertices, faces = mesh.vertices.astype(np.float64), mesh.faces.astype(np.int32)
    assert mesh.used.all()  # every vertex is a point of the surface
    lap = heatcurv.PointCloudLaplacian(vertices)
    sources = {"ear": int(np.argmax(vertices[:, 1])), "foot": int(np.argmin(vertices[:, 1])),
               "back": int(np.argmax(vertices[:, 0]))}
    exact = geodesic.PyGeodesicAlgorithmExact(vertices, faces)
    errors = {}
    for name, source in sources.items():
        truth = exact.geodesicDistances(np.array([source]), None)[0]
        distance = lap.geodesic_distance(source)
        others = truth > 0
        errors[name] = 100 * float(np.mean(np.abs(distance[others] - truth[others]) / truth[others]))
    records.check("real_geodesic/bunny-obj-28088", **errors)
