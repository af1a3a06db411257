"""Fixtures of the command-line tests: a sphere cloud with properties, and ``compute`` run on it."""

import numpy as np
import pytest
from cli_helpers import run

import heatcurv
from heatcurv import io, surfaces


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("cli")


@pytest.fixture(scope="module")
def sphere_cloud():
    """3000 random points on the unit sphere, with colours and an intensity property."""
    sample = surfaces.Sphere().sample(3000, "random", seed=3)
    rng = np.random.default_rng(0)
    colors = rng.integers(0, 256, size=(3000, 3))
    intensity = rng.integers(0, 65536, size=3000).astype(np.uint16)
    return sample.points, colors, intensity


@pytest.fixture(scope="module")
def sphere_ply(workdir, sphere_cloud):
    points, colors, intensity = sphere_cloud
    path = workdir / "sphere.ply"
    io.write_points(path, points, {"intensity": intensity}, colours=colors)
    return path


@pytest.fixture(scope="module")
def sphere_fields_ply(workdir, sphere_ply):
    """``heatcurv compute sphere.ply -o sphere_fields.ply``: the process and its output."""
    path = workdir / "sphere_fields.ply"
    return run("compute", sphere_ply, "-o", path), path


@pytest.fixture(scope="module")
def sphere_reference(sphere_cloud):
    """The library run in this process on the same points."""
    return heatcurv.estimate(sphere_cloud[0])
