"""heatcurv.reliability: the flags that compare a point with the whole cloud's medians."""

import warnings

import numpy as np
import pytest

from heatcurv.errors import HeatcurvWarning
from heatcurv.reliability import (
    MISFIT_FACTOR,
    MISFIT_FLOOR,
    RESOLUTION_LIMIT,
    ReliabilityInputs,
    cloud_flags,
    misfit_baselines,
    misfits,
    resolution,
)


def _inputs(n=1000):
    width = np.where(np.arange(n) < n // 2, 60, 240)
    # residuals spread evenly about 0.01 (width 60) and 0.05 (width 240): medians exactly those
    residual = np.where(width == 60, 0.01, 0.05) * np.tile(np.linspace(0.5, 1.5, n // 2), 2)
    return ReliabilityInputs(np.ones(n, bool), residual, width, np.full(n, 0.1), np.ones(n, bool))


def test_misfits_are_judged_against_their_own_widths_median():
    inputs = _inputs()
    base = misfit_baselines(inputs.residual, inputs.width, inputs.counted)
    assert base[60] == pytest.approx(0.01, rel=1e-12) and base[240] == pytest.approx(0.05, rel=1e-12)
    residual = inputs.residual.copy()
    residual[[0, 600]] = [MISFIT_FACTOR * 0.012, MISFIT_FACTOR * 0.012]  # a misfit at 60, not at 240
    flags = misfits(residual, inputs.width, base)
    assert flags[0] and not flags[600] and flags.sum() == 1
    # uncounted points (outliers, duplicates) do not move the median; the floor holds for clean clouds
    assert misfit_baselines(np.zeros(10), np.zeros(10, int), np.ones(10, bool)) == {0: MISFIT_FLOOR}


def test_cloud_flags_join_local_flags_misfits_and_resolution():
    inputs = _inputs()
    reliable, rho = cloud_flags(inputs)
    assert reliable.all() and rho == pytest.approx(0.1)
    # the medians given (a tiled run's, over all tiles) are used as they are
    reliable, _ = cloud_flags(inputs, baselines={60: 1e-4, 240: 1.0}, resolution_value=0.1)
    assert not reliable[:500].any() and reliable[500:].all()
    coarse = ReliabilityInputs(inputs.local, None, inputs.width, np.full(1000, 2 * RESOLUTION_LIMIT), inputs.counted)
    with pytest.warns(HeatcurvWarning, match="too coarse"):
        reliable, rho = cloud_flags(coarse)
    assert not reliable.any() and rho == pytest.approx(2 * RESOLUTION_LIMIT)
    assert resolution(np.array([np.nan, 0.2, 0.4]), np.array([True, True, False])) == pytest.approx(0.2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        part = inputs.take(np.arange(10))
        assert part.residual.shape == (10,) and cloud_flags(part)[0].all()
