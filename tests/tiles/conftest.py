"""Shared clouds of the tiled-run tests: small files forced into several tiles, computed once."""

import numpy as np
import pytest

import heatcurv
from heatcurv.tiles import compute_file

#: Every field a tiled run writes (float64 so that the comparison sees the computation, not float32).
ALL_FIELDS = ("nx", "ny", "nz", "mean", "gaussian", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area",
              "reliable", "border", "outlier", "spacing", "neighbours", "fit_radius")


@pytest.fixture(scope="session")
def torus_file(tmp_path_factory):
    """A clean random torus (R = 2.3701, r = 1), 12000 points, as an NPY file; and its sample."""
    sample = heatcurv.surfaces.Torus().sample(12000, "random", seed=3)
    path = tmp_path_factory.mktemp("torus") / "torus.npy"
    np.save(path, sample.points)
    return path, sample


@pytest.fixture(scope="session")
def torus_memory(torus_file):
    """The in-memory estimate of the torus (outward normals)."""
    return heatcurv.estimate(torus_file[1].points)


@pytest.fixture(scope="session")
def torus_threads(torus_file, tmp_path_factory):
    """The torus in 8 tiles on 2 threads, every field as float64 PLY: (path, report)."""
    out = tmp_path_factory.mktemp("threads") / "torus.ply"
    report = compute_file(torus_file[0], out, tile_size=2500, tile_workers=2, scheduler="threads",
                          dtype="float64", fields=ALL_FIELDS, max_memory="4G")
    return out, report


def read_fields(path):
    """Every column of an output file, by name (x y z too)."""
    from heatcurv.io import read_points

    cloud = read_points(path)
    columns = {a: cloud.points[:, k] for k, a in enumerate("xyz")}
    if cloud.normals is not None:
        columns.update({a: cloud.normals[:, k] for k, a in enumerate(("nx", "ny", "nz"))})
    columns.update(cloud.fields)
    return columns
