"""heatcurv.scale: the kernel-width choice between chord and denoised fits, and the coarse level."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import surfaces
from heatcurv.areas import density_areas
from heatcurv.neighbourhood import knn_neighbourhood
from heatcurv.scale import FitLevel, Scale, ScaleReport, fit_at_scale, fit_blocks, select_scale


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


def test_scale_report_reads_by_attribute_and_by_key():
    sample = surfaces.Torus().sample(4000, "random", seed=5)
    report = heatcurv.estimate(sample.points).info["scale"]
    assert isinstance(report, ScaleReport)
    assert report["k"] == report.k == 60 and report.get("fit") == report.fit == "chord-60"
    assert report.get("nothing", 7) == 7 and set(report.keys()) == set(report.as_dict())
    with pytest.raises(KeyError):
        report["nothing"]
    assert 0 < report.median_h < report.radius


def test_fit_level_is_the_cloud_up_to_k_fit_then_a_coarser_random_level():
    pts = surfaces.Sphere().sample(20_000, "random", seed=1).points
    tree = cKDTree(pts)
    full = FitLevel.for_kernel(pts, tree, 240, k_fit=240)
    assert full.source is None and full.fraction == 1.0 and full.k == 240 and full.tree is tree
    coarse = FitLevel.for_kernel(pts, tree, 960, k_fit=240, seed=3)
    assert coarse.fraction == pytest.approx(0.25) and coarse.k == 240
    assert np.all(np.diff(coarse.source) > 0) and len(coarse.points) == 5000
    again = FitLevel.for_kernel(pts, tree, 960, k_fit=240, seed=3)
    np.testing.assert_array_equal(again.source, coarse.source)  # seeded: reproducible
    nb = coarse.neighbourhood(pts[:10])
    assert nb.n_points == 10 and np.all(nb.counts == 240) and nb.indices.max() < len(pts)
    assert set(nb.indices) <= set(coarse.source)
    assert coarse.rows_per_block(24_000) == 100


def test_a_base_kernel_wider_than_the_ladder_cap_is_still_a_candidate():
    # before: neighbours above max(1920, n // 10) left the ladder empty (IndexError)
    pts = heatcurv.surfaces.Sphere().sample(400, "random", seed=1).points
    res = heatcurv.estimate(pts, neighbours=398)
    assert res.info["scale"].k == 398
    assert np.median(res.mean) == pytest.approx(1.0, rel=0.05)  # the ball holds the whole sphere
