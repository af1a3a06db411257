"""A winding-number orientation to measure heatcurv against: the iteration of WNNC on every point.

Lin, Shi and Liu 2024, "Fast and Globally Consistent Normal Orientation based on the Winding Number
Normal Consistency" (ACM ToG 43(6); code at github.com/jsnln/WNNC, which needs a PyTorch extension
and is not on PyPI). heatcurv re-implements its iteration in :mod:`heatcurv.orient.consistency`, where
it runs over the winding sources as a second opinion on their sides; here it orients every point of a
cloud on its own, as the authors' method does, with their three width presets (in the box the points
are scaled into): ``l0`` (noise-free uniform points), ``l1`` (real scans, heatcurv's), ``l2`` (noise of
0.25 %), and their 40 steps.
"""

from __future__ import annotations

import numpy as np

from heatcurv.orient.consistency import field_normals

#: the authors' width presets: (narrowest, widest), in the scaled coordinates
PRESETS = {"l0": (0.002, 0.016), "l1": (0.01, 0.04), "l2": (0.02, 0.08)}
#: the authors' number of steps
ITERATIONS = 40


def wnnc_normals(points: np.ndarray, preset: str = "l0", iterations: int = ITERATIONS) -> np.ndarray:
    """Unit normals of ``points`` (shape (n, 3)) by the WNNC iteration, shape (n, 3), oriented outward."""
    return field_normals(points, PRESETS[preset], iterations)
