"""What a run decides once for the whole cloud, so that a part of it computes as the whole would.

Most of :func:`heatcurv.estimate` is local: a point's values depend only on the
points within its support radius (``info["scale"].support_radius``). A few
choices are not, and a tiled run (:mod:`heatcurv.tiles`) must make them once
for the whole cloud and hand them to every tile, or its tiles would disagree
at their seams:

* the **frame**: the centring origin and length unit every coordinate is
  computed in (:func:`heatcurv.geometry.validation.prepare_points`), and the centroid,
  root-mean-square radius and size that make the sampling keys
  (:func:`heatcurv.geometry.sampling.geometric_keys`) the same wherever a point is
  computed;
* the **kernel widths**: the noise level and Lepski's choice, made at sample
  centres over the whole cloud (:func:`heatcurv.choice.scale.select_scale`; a tiled
  run measures the centres tile by tile, :mod:`heatcurv.choice.survey`);
* the **orientation policy** of ``orient="auto"`` without a viewpoint
  (:func:`heatcurv.orient.auto.auto_policy`: "up" for an open surface over
  the horizontal plane, else "outward"), decided on the same sample centres;
* the **medians** the reliability flags compare against (the misfit baselines
  and the resolution check, :mod:`heatcurv.estimator`), taken over every point
  after the fit.

:func:`heatcurv.estimate` makes all of them from the points it holds; given
:class:`CloudChoices` it takes the frame, the kernel widths and the orientation policy from them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import HeatcurvError

__all__ = ["CloudChoices", "CloudFrame", "FrameStats", "frame_of"]


@dataclass(frozen=True)
class CloudFrame:
    """The coordinate frame of a whole cloud.

    Attributes
    ----------
    offset : ndarray, shape (3,)
        Centring origin, input units: the centre of the cloud's bounding box.
    unit : float
        Length unit of the stages, input units (a power of two, 1 for all but
        extreme extents: :func:`heatcurv.geometry.validation.prepare_points`).
    n_points : int
        Rows of the cloud (duplicates included).
    centroid : ndarray, shape (3,)
        Mean of the rows, in the stages' frame (``(x - offset) / unit``).
    rms_radius : float
        Root-mean-square distance of the rows from ``centroid``, stages' unit.
    """

    offset: np.ndarray
    unit: float
    n_points: int
    centroid: np.ndarray
    rms_radius: float

    def to_stage(self, points: np.ndarray) -> np.ndarray:
        """``(points - offset) / unit``, shape as ``points`` (exactly as :func:`prepare_points` centres)."""
        return (np.asarray(points, dtype=np.float64) - self.offset) / self.unit + 0.0


def frame_of(prepared) -> CloudFrame:
    """The frame of a cloud held in memory: moments of its *distinct* points.

    Exact duplicates count once (adding duplicates of some points changes no
    result: the contract of :func:`heatcurv.estimate`), so a tiled run takes
    its moments over each tile's distinct points (:meth:`FrameStats.add_distinct`).

    Parameters
    ----------
    prepared : heatcurv.geometry.validation.PreparedPoints
        The whole cloud, centred and merged.

    Returns
    -------
    CloudFrame
    """
    pts = prepared.points
    centroid = pts.mean(axis=0)
    d = pts - centroid
    rms = float(np.sqrt(np.mean(np.einsum("ij,ij->i", d, d))))
    return CloudFrame(np.asarray(prepared.offset, dtype=np.float64), float(prepared.unit), int(pts.shape[0]),
                      centroid, rms)


class FrameStats:
    """Accumulates a :class:`CloudFrame` over chunks of rows (one streaming pass).

    The moments are summed about the first chunk's first row, so that
    coordinates of 1e6 and more (UTM) lose no precision, and per chunk in
    float64: the frame differs from the in-memory one only by rounding.

    Examples
    --------
    >>> import numpy as np
    >>> pts = np.random.default_rng(0).normal(size=(1000, 3))
    >>> stats = FrameStats()
    >>> for chunk in np.array_split(pts, 7):
    ...     stats.add(chunk)
    >>> bool(np.allclose(stats.frame().centroid + stats.frame().offset, pts.mean(axis=0)))
    True
    """

    def __init__(self):
        self.n = 0
        self.low = np.full(3, np.inf)
        self.high = np.full(3, -np.inf)
        self.origin: np.ndarray | None = None
        self.total = np.zeros(3)
        self.total_sq = 0.0

    def add(self, chunk) -> None:
        """Add rows, shape (m, 3)."""
        chunk = np.asarray(chunk, dtype=np.float64)
        if chunk.ndim != 2 or chunk.shape[1] != 3:
            raise HeatcurvError(f"a chunk of points must have shape (m, 3), got {chunk.shape}")
        if chunk.shape[0] == 0:
            return
        if not np.isfinite(chunk).all():
            raise HeatcurvError("points hold NaN or infinite coordinates; remove or repair them first")
        if self.origin is None:
            self.origin = chunk[0].copy()
        shifted = chunk - self.origin
        self.n += chunk.shape[0]
        self.low = np.minimum(self.low, chunk.min(axis=0))
        self.high = np.maximum(self.high, chunk.max(axis=0))
        self.total += shifted.sum(axis=0)
        self.total_sq += float(np.einsum("ij,ij->", shifted, shifted))

    def add_distinct(self, chunk, frame: CloudFrame) -> None:
        """Add a part's rows counting exact duplicates once, as :func:`frame_of` does in memory.

        Every duplicate of a row must be in the same chunk (a tile's core holds
        all the points at its positions). Duplicates are found in the stages'
        coordinates ``frame.to_stage(chunk)``, as :func:`heatcurv.geometry.validation.prepare_points`
        finds them.
        """
        chunk = np.asarray(chunk, dtype=np.float64)
        if chunk.shape[0] == 0:
            return
        from ..geometry.validation import distinct_rows

        first, _ = distinct_rows(frame.to_stage(chunk))
        self.add(chunk if first.size == chunk.shape[0] else chunk[first])

    def frame(self) -> CloudFrame:
        """The frame of every row added so far."""
        from ..geometry.validation import bounding_box_frame

        if self.n == 0:
            raise HeatcurvError("points is empty: a point cloud needs at least a few points")
        offset, unit = bounding_box_frame(self.low, self.high)
        mean_shifted = self.total / self.n
        variance = max(self.total_sq / self.n - float(mean_shifted @ mean_shifted), 0.0)
        centroid = (self.origin + mean_shifted - offset) / unit
        return CloudFrame(offset, unit, self.n, centroid, float(np.sqrt(variance)) / unit)


@dataclass(frozen=True)
class CloudChoices:
    """Every choice a part of the cloud takes from the whole (see the module docstring).

    Attributes
    ----------
    frame : CloudFrame
    scale : heatcurv.choice.scale.ScaleChoice or None
        The kernel widths, with the sample centres they were chosen at
        (``centres``, ``k_centre``); None: chosen from the points at hand.
    orientation : heatcurv.orient.orientation.AutoPolicy or None
        What ``orient="auto"`` without a viewpoint orients by; None: decided on the points at hand.
    """

    frame: CloudFrame
    scale: object | None = None
    orientation: object | None = None
