"""heatcurv.scale: the kernel-width choice between chord and denoised fits, and the coarse level."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.scale import Scale, fit_at_scale, select_scale


def test_select_scale_clean_and_noisy():
    for noise, expect_clean in [(0.0, True), (0.006, False)]:
        sample = surfaces.Torus().sample(8000, "random", seed=2, noise=noise)
        op = heatcurv.build_operator(sample.points)
        normals = sample.normals[op.prepared.first]
        choice = select_scale(op.points, op.tree, normals, op.areas)
        if expect_clean:
            assert choice.scale == Scale(60, False)
        else:
            assert choice.scale.denoise and choice.scale.k >= 480
            # measured 0.97 of the true noise
            assert choice.sigma == pytest.approx(sample.sigma, rel=0.2)
            assert choice.sd == sorted(choice.sd, reverse=True)  # wider kernels: less variance


def test_coarse_level_keeps_the_cost_bounded():
    sample = surfaces.Sphere().sample(8000, "random", seed=4, noise=0.003)
    op = heatcurv.build_operator(sample.points)
    nrm = sample.normals[op.prepared.first]
    fit, h, nb, fraction = fit_at_scale(op.points, op.tree, nrm, op.areas, Scale(960, True), k_fit=240)
    assert fraction == pytest.approx(0.25, rel=0.01)
    # about 240 coarse neighbours per ball instead of 960
    assert 200 < nb.counts.mean() < 280
    assert np.mean(np.abs(fit.principal.mean - 1.0)) < 0.05
