"""The real scans: pymeshlab's sample meshes and CGAL's closed models, fetched once per session.

See support.scans.  Without a network (or pip, or apt-get and
urllib) the tests here are skipped with the reason; CI sets
``HEATCURV_REQUIRE_REAL_SCANS=1`` so that a failed fetch fails them instead.
"""

import os

import pytest

from support.scans import ScanDataUnavailable, fetch_cgal_meshes, fetch_pymeshlab_samples


def _fetched(fetch):
    """``fetch()``, or skip (fail when ``HEATCURV_REQUIRE_REAL_SCANS=1``) with the reason it failed."""
    try:
        return fetch()
    except ScanDataUnavailable as exc:
        reason = str(exc)
    if os.environ.get("HEATCURV_REQUIRE_REAL_SCANS") == "1":
        pytest.fail(f"real scans not available (and HEATCURV_REQUIRE_REAL_SCANS=1): {reason}")
    pytest.skip(f"real scans not available: {reason}")


@pytest.fixture(scope="session")
def pymeshlab_samples():
    """Directory holding ``bunny.obj``, ``rangemaps/face000.ply`` and the other pymeshlab samples."""
    return _fetched(fetch_pymeshlab_samples)


@pytest.fixture(scope="session")
def cgal_meshes():
    """Directory holding ``camel.off`` and the other :data:`~support.scans.CGAL_MESHES`."""
    return _fetched(fetch_cgal_meshes)
