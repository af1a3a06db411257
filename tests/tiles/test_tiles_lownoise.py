"""Tiles under very low noise: the widened kernel and the anchors' regression keep the tiled run exact.

The regression's degree is heatcurv.fits.anchors.carry_degree.
"""

import numpy as np
from tiles_helpers import ALL_FIELDS, exact

import heatcurv
from heatcurv.choice.scale import in_low_noise_band
from heatcurv.tiles import compute_file
from support.tiles import tiled_agreement


def test_low_noise_cloud_equals_in_memory(tmp_path):
    """A torus with noise 1e-5 of its diagonal (coordinate rounding): the kernel widened one doubling beyond
    Lepski's choice (the survey fits those candidates too, for the halo), anchors 24 per ball, each point's
    tensor regressed from its 24 nearest anchors, whose reach the support radius counts; the tiles
    equal the in-memory run on every field of every point."""
    sample = heatcurv.surfaces.Torus(0.6, 1.4).sample(20_000, "random", seed=5, noise=1e-5)
    src, out = tmp_path / "low.npy", tmp_path / "low.ply"
    np.save(src, sample.points)
    memory = heatcurv.estimate(sample.points)
    scale = memory.info["scale"]
    assert in_low_noise_band(scale.relative_noise) and 0 < scale.anchors < 20_000
    report = compute_file(src, out, tile_size=5000, scheduler="serial", dtype="float64", fields=ALL_FIELDS)
    assert report.tiles >= 4
    agreement = tiled_agreement(out, memory, rtol=0.0)  # bit for bit (measured)
    assert exact(agreement) == dict.fromkeys(agreement, (0, 0.0))
