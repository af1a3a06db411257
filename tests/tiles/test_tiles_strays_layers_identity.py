"""Strays and layered balls in tiles: the flags that read the neighbours' flags equal the in-memory run.

A point is a stray when most of its ball is (:mod:`heatcurv.flags.outliers`, test 4), and a second sheet when
most of its 20 nearest have balls split in two layers (:func:`heatcurv.flags.sheets.second_sheet`): both read
flags of neighbours, which the tiles' halo must hold with the points those flags depend on.
"""

import numpy as np
import pytest
from tiles_helpers import ALL_FIELDS

import heatcurv
from heatcurv.tiles import compute_file
from support.tiles import tiled_agreement


def _veiled_plane():
    """A dense square with a sparse veil hanging over one edge (mixed pixels), as test_outliers builds it."""
    rng = np.random.default_rng(3)
    plane = np.c_[rng.uniform(-1, 1, (6000, 2)), np.zeros(6000)]
    veil = np.c_[rng.uniform(0.9, 1.1, 80), rng.uniform(-1, 1, 80), rng.uniform(0.02, 0.3, 80)]
    return np.vstack([plane, veil])


def _thin_plate():
    """An ellipsoid 1 x 1 x 0.02 of 6000 points: under two spacings thick, its balls layered."""
    return heatcurv.surfaces.Ellipsoid(1.0, 1.0, 0.02).sample(6000, "random", seed=0).points


@pytest.mark.parametrize("make", [_veiled_plane, _thin_plate], ids=["veil", "plate"])
def test_strays_and_second_sheets_in_tiles_equal_in_memory(make, tmp_path):
    points = make()
    memory = heatcurv.estimate(points)
    # what the test is about: strays (veil) and second sheets (plate) there to be found
    assert memory.outlier.sum() >= 20 if make is _veiled_plane else memory.info["second_sheet"] >= 0.5 * len(points)
    src, out = tmp_path / "cloud.npy", tmp_path / "out.ply"
    np.save(src, points)
    report = compute_file(src, out, tile_size=len(points) // 4, scheduler="serial", dtype="float64",
                          fields=ALL_FIELDS)
    assert report.tiles >= 4
    agreement = tiled_agreement(out, memory, rtol=2e-14)
    assert {name: a["bad"] for name, a in agreement.items()} == dict.fromkeys(agreement, 0)
    assert all(agreement[name]["worst"] == 0.0 for name in ("reliable", "outlier"))
