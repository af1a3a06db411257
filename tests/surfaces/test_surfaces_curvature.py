"""Tests of heatcurv.surfaces.curvature: the exact-curvature record is an orthonormal, right-handed frame
with k1 >= k2, mean = (k1 + k2) / 2, gaussian = k1 k2 and the documented umbilic rule, for every
surface and sampler.
"""

from __future__ import annotations

import numpy as np
import pytest
from surfaces_helpers import CASES

from heatcurv import surfaces as hs


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("sampler", hs.SAMPLERS)
def test_frame_is_orthonormal_and_right_handed(case, sampler):
    surf = CASES[case]()
    smp = surf.sample(400, sampler=sampler, seed=3)  # includes border, fold, near-poles
    n, d1, d2 = smp.normals, smp.d1, smp.d2
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-14)
    assert np.allclose(np.linalg.norm(d1, axis=1), 1.0, atol=1e-14)
    assert np.allclose(np.linalg.norm(d2, axis=1), 1.0, atol=1e-14)
    assert np.max(np.abs(np.einsum("ij,ij->i", d1, n))) < 1e-14
    assert np.max(np.abs(np.einsum("ij,ij->i", d2, n))) < 1e-14
    assert np.max(np.abs(np.cross(d1, d2) - n)) < 1e-14
    assert np.all(smp.k1 >= smp.k2)
    assert np.allclose(smp.mean, 0.5 * (smp.k1 + smp.k2), rtol=1e-14, atol=1e-15)
    assert np.allclose(smp.gaussian, smp.k1 * smp.k2, rtol=1e-14, atol=1e-15)
    tol = 1e-9 * np.maximum(1.0, np.maximum(np.abs(smp.k1), np.abs(smp.k2)))
    assert np.array_equal(smp.umbilic, smp.k1 - smp.k2 <= tol)
