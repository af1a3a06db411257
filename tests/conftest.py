"""Shared fixtures: analytic samples and their estimates, computed once per session."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces


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


def aligned_exact(sample, res):
    """Exact values re-expressed for the estimate's normal orientation.

    Graph normals point up; heatcurv orients open patches by its own rule. If
    the estimated normals point the other way, the signed curvatures change
    sign and k1 <-> -k2, d1 <-> d2.
    """
    flip = np.mean(np.sign(np.einsum("ij,ij->i", res.normals, sample.normals))) < 0
    s = -1.0 if flip else 1.0
    return {
        "normals": s * sample.normals,
        "mean": s * sample.mean,
        "k1": -sample.k2 if flip else sample.k1,
        "k2": -sample.k1 if flip else sample.k2,
        "d1": sample.d2 if flip else sample.d1,
        "gaussian": sample.gaussian,
    }


def rel_l1(est, exact):
    """Relative L1 error, mean|est - exact| / mean|exact|."""
    return float(np.mean(np.abs(est - exact)) / np.mean(np.abs(exact)))


def angle_deg(a, b):
    """Mean angle between unit line directions (sign ignored), degrees."""
    c = np.clip(np.abs(np.einsum("ij,ij->i", a, b)), 0.0, 1.0)
    return float(np.degrees(np.mean(np.arccos(c))))
