"""Tests of heatcurv.surfaces.noise: the Gaussian noise of the samples.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from surfaces_helpers import CASES


@pytest.mark.parametrize("case", ["sphere", "torus", "saddle", "folded_90"])
def test_noise_sigma(case):
    surf = CASES[case]()
    noisy = surf.sample(20000, "fibonacci", noise=0.01, seed=5)
    clean = surf.sample(20000, "fibonacci")
    diag = np.linalg.norm(noisy.clean_points.max(0) - noisy.clean_points.min(0))
    assert noisy.sigma == pytest.approx(0.01 * diag, rel=1e-15)
    e = noisy.points - noisy.clean_points
    # 60000 Gaussian values: the sample std has relative std 1/sqrt(2 * 60000) ~ 0.3 %
    assert np.std(e) == pytest.approx(noisy.sigma, rel=0.015)
    # isotropic: each coordinate on its own (20000 values, rel. std 0.5 %)
    assert np.allclose(np.std(e, axis=0), noisy.sigma, rtol=0.03)
    assert np.all(np.abs(np.mean(e, axis=0)) < 5 * noisy.sigma / math.sqrt(20000))
    # exact values are those of the clean points
    for name in ("clean_points", "normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "u", "v"):
        assert np.array_equal(getattr(noisy, name), getattr(clean, name))
