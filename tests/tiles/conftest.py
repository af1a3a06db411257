"""Shared clouds of the tiled-run tests: small files forced into several tiles, computed once."""

import numpy as np
import pytest
from tiles_helpers import ALL_FIELDS

import heatcurv
from heatcurv.tiles import compute_file


@pytest.fixture(scope="session")
def torus_file(tmp_path_factory):
    """A clean random torus (R = 2.3701, r = 1), 6000 points, as an NPY file; and its sample."""
    sample = heatcurv.surfaces.Torus().sample(6000, "random", seed=3)
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
    report = compute_file(torus_file[0], out, tile_size=1200, tile_workers=2, scheduler="threads",
                          dtype="float64", fields=ALL_FIELDS, max_memory="4G")
    return out, report
