"""Shared fixtures: analytic samples and their estimates, computed once per session."""

import os

import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import surfaces
from heatcurv.geometry.neighbourhood import knn_neighbourhood
from records import Records


def pytest_configure(config):
    """Give each of several test processes one BLAS thread.

    pytest-xdist starts one test process per core. OpenBLAS, numpy's linear algebra, would start a
    thread per core in each of them, and its threads wait for work by spinning, taking the cores the
    other process computes on: one BLAS thread each makes the run about 15 % faster on two cores (no
    difference in a single process). The workers inherit the variables, set here before they start.
    """
    if not hasattr(config, "workerinput") and (getattr(config.option, "numprocesses", 0) or 0) > 1:
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(name, "1")


def pytest_addoption(parser):
    parser.addoption(
        "--update-records",
        action="store_true",
        help="rewrite tests/records.json with the errors measured by the tests that run, instead of checking them",
    )


@pytest.fixture(scope="session")
def records(request):
    """The accuracy records (tests/records.py): ``records.check(key, metric=error, ...)``."""
    table = Records(update=request.config.getoption("--update-records"))
    yield table
    table.write()


@pytest.fixture(scope="session")
def sphere_sample():
    """Fibonacci sphere of radius 1, 4000 points: the paper's regular setting."""
    return surfaces.Sphere(radius=1.0).sample(4000, "fibonacci")


@pytest.fixture(scope="session")
def sphere_paper(sphere_sample):
    return heatcurv.estimate(sphere_sample.points, method="paper")


@pytest.fixture(scope="session")
def torus_sample():
    """The paper's torus (r1 = 1, r2 = 2.3701), area-uniform Fibonacci lattice, 8000 points."""
    return surfaces.Torus().sample(8000, "fibonacci")


@pytest.fixture(scope="session")
def torus_default(torus_sample):
    return heatcurv.estimate(torus_sample.points)


@pytest.fixture(scope="module")
def plane_grid():
    """The unit square (x, y in [-1, 1], z = 0) on a 61 x 61 grid: step 1/30."""
    return surfaces.Plane().sample(61 * 61, "grid")


@pytest.fixture(scope="module")
def torus_cloud():
    pts = surfaces.Torus().sample(6000, "random", seed=3).points
    tree = cKDTree(pts)
    return pts, tree, knn_neighbourhood(pts, 40, tree=tree)
