"""The real scans: pymeshlab's sample meshes, fetched once per session (see heatcurv.testing.scans).

Without a network (or pip) the tests here are skipped with the reason; CI sets
``HEATCURV_REQUIRE_REAL_SCANS=1`` so that a failed fetch fails them instead.
"""

import os

import pytest

from heatcurv.testing.scans import ScanDataUnavailable, fetch_pymeshlab_samples


@pytest.fixture(scope="session")
def pymeshlab_samples():
    """Directory holding ``bunny.obj``, ``rangemaps/face000.ply`` and the other pymeshlab samples."""
    try:
        return fetch_pymeshlab_samples()
    except ScanDataUnavailable as exc:
        reason = str(exc)
    if os.environ.get("HEATCURV_REQUIRE_REAL_SCANS") == "1":
        pytest.fail(f"real scans not available (and HEATCURV_REQUIRE_REAL_SCANS=1): {reason}")
    pytest.skip(f"real scans not available: {reason}")
