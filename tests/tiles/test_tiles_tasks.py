"""The halo certificate: the halo a tile's core points need, exactly."""

import numpy as np

from heatcurv.tiles.compute import DEPTH
from heatcurv.tiles.tasks import certificate

BOX = (np.zeros(3), np.full(3, 10.0))
CLOUD = (np.full(3, -100.0), np.full(3, 100.0))


def _need(points, reach, halo, cloud=CLOUD):
    """The certificate's answer for dependency radii ``reach`` (``DEPTH x support``) and a halo width."""
    support = np.asarray(reach, dtype=float) / DEPTH
    return certificate(np.asarray(points, dtype=float), support, BOX, (BOX[0] - halo, BOX[1] + halo), cloud)


def test_every_ball_inside_the_halo_box():
    points = [[1.0, 5, 5], [9.5, 5, 5]]
    # a reach of 1.0 from x = 9.5 needs 0.5 beyond the core box
    assert _need(points, [1.0, 1.0], 0.5) == 0.0
    assert _need(points, [1.0, 1.0], 0.4) == 0.5


def test_the_widest_need_is_reported():
    assert _need([[0.2, 5, 5], [5, 5, 9.0]], [2.0, 6.0], 1.0) == 5.0


def test_no_need_across_the_cloud_edge():
    cloud = (np.array([0.0, -100, -100]), CLOUD[1])  # nothing lies beyond x = 0
    assert _need([[0.1, 5, 5]], [4.0], 1.0, cloud) == 0.0
    assert _need([[0.1, 5, 5]], [4.0], 1.0) == 3.9
