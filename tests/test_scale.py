"""heatcurv.scale: the kernel-width choice between chord and denoised fits, and the coarse level."""

import numpy as np
import pytest

import heatcurv
from heatcurv import surfaces
from heatcurv.areas import density_areas
from heatcurv.neighbourhood import knn_neighbourhood
from heatcurv.scale import Scale, fit_at_scale, fit_blocks, select_scale


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


def test_fit_blocks_reuse_and_block_size_change_nothing(torus_cloud):
    pts, tree, _ = torus_cloud
    sample = surfaces.Torus().sample(6000, "random", seed=3)
    base = knn_neighbourhood(pts, 60, tree=tree)
    areas = density_areas(base)
    whole, h, nb, _ = fit_at_scale(pts, tree, sample.normals, areas, Scale(60, False))
    parts = list(fit_blocks(pts, tree, sample.normals, areas, Scale(60, False), base=base, block_pairs=50_000))
    assert len(parts) > 5
    k1 = np.concatenate([p[3].principal.k1 for p in parts])
    np.testing.assert_allclose(k1, whole.principal.k1, rtol=1e-12)
    np.testing.assert_allclose(h, base.radius / 2, rtol=1e-15)
    # coarse level for wide kernels: the pairs per centre stay at about k_fit
    *_, nbw, fraction = fit_at_scale(pts, tree, sample.normals[:100], areas, Scale(960, True), centres=np.arange(100))
    assert fraction == pytest.approx(0.25, rel=0.01) and np.all(nbw.counts <= 241)
