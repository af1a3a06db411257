"""Input checks, centring and duplicate merging: the boundary of the numerical core.

Every public entry point passes its coordinates through :func:`prepare_points`
first, so the stages after it can assume a finite ``(m, 3)`` float64 array of
distinct points, centred near the origin (scans come in UTM-like coordinates of
1e6 and more; centring first keeps the differences ``xi - xj`` exact to the last
bits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import HeatcurvError

__all__ = [
    "PreparedPoints", "bounding_box_frame", "distinct_rows", "row_hashes", "prepare_points", "prepare_normals",
    "EXTENT_RANGE", "UNIT_BAND",
]

#: Clouds whose extent (largest bounding-box side, input units) lies outside this range are
#: refused: their areas (extent^2 / n) or Gaussian curvatures (n / extent^2) would leave the
#: range of double precision (about 1e-308 to 1e308) on clouds of up to 1e9 points.
EXTENT_RANGE = (1e-140, 1e140)
#: Extents inside this band are computed in input units (``unit = 1``); outside it the points
#: are divided by a power of two that brings the extent to about 1 (the stages square distances
#: and raise spacings to the fourth power: measured, unscaled clouds of extent above 1e77 or
#: below 1e-78 gave wrong normals and curvatures, above 1e155 crashed).
UNIT_BAND = (2.0**-40, 2.0**40)


@dataclass(frozen=True)
class PreparedPoints:
    """Distinct, centred points and the map back to the caller's rows.

    Attributes
    ----------
    points : ndarray, shape (m, 3), float64
        The distinct input points minus ``offset``: in input order if there
        were no duplicates, else in lexicographic order (:meth:`reordered`
        puts them in another, e.g. spatial, order).
    offset : ndarray, shape (3,)
        What was subtracted (the centre of the bounding box), input units.
    inverse : ndarray, shape (n,), int64
        ``points[inverse]`` are the caller's points (centred), row for row:
        exact duplicates share one row and so get their twin's values.
    first : ndarray, shape (m,), int64
        For each distinct point, the first input row that holds it.
    unit : float
        The length unit of ``points``, in input units: ``points = (input -
        offset) / unit``. 1 unless the cloud spans less than ``2**-40`` or more
        than ``2**40`` input units (:data:`UNIT_BAND`); then a power of two
        (an exact division) that brings its extent to about 1, so that no
        square or fourth power of a distance overflows or underflows in the
        stages. Lengths computed on ``points`` are multiplied by ``unit`` to
        return to input units, curvatures divided by it.
    """

    points: np.ndarray
    offset: np.ndarray
    inverse: np.ndarray
    first: np.ndarray
    unit: float = 1.0

    @property
    def n_input(self) -> int:
        """Number of input rows, duplicates included."""
        return int(self.inverse.shape[0])

    @property
    def n_distinct(self) -> int:
        """Number of distinct points used by the computation."""
        return int(self.points.shape[0])

    def reordered(self, order: np.ndarray) -> PreparedPoints:
        """The same points in the order ``points[order]``, with the maps back updated.

        Parameters
        ----------
        order : ndarray of int, shape (m,)
            A permutation of the distinct points, e.g. the leaf order of a
            k-d tree: neighbours then lie close in memory, which makes every
            later gather over neighbour pairs cache-friendly (it halves the
            60-neighbour k-d tree query on a million random points).
        """
        order = np.asarray(order)
        rank = np.empty(order.shape[0], dtype=np.int64)
        rank[order] = np.arange(order.shape[0])
        return PreparedPoints(
            points=np.take(self.points, order, axis=0), offset=self.offset, inverse=rank[self.inverse],
            first=self.first[order], unit=self.unit,
        )

    def to_input_order(self, values: np.ndarray) -> np.ndarray:
        """Expand per-distinct-point ``values`` (shape ``(m, ...)``) to the input rows."""
        # np.take: the same rows as values[self.inverse], 3x faster for (m, 3) arrays
        return np.take(values, self.inverse, axis=0)

    def share_among_duplicates(self, values: np.ndarray) -> np.ndarray:
        """Expand an additive per-point quantity (an area): duplicates split their point's value.

        Returns
        -------
        ndarray, shape (n,)
            Sums over the input rows equal sums over the distinct points.
        """
        multiplicity = np.bincount(self.inverse, minlength=self.n_distinct)
        return (values / multiplicity)[self.inverse]


def _as_float_array(points, name: str) -> np.ndarray:
    """``points`` as float64; complex numbers (an imaginary part would be dropped) and booleans (a mask) refused."""
    def not_numeric(exc):
        return HeatcurvError(f"{name} must be numeric array-like of shape (n, 3): {exc}")

    try:
        raw = np.asarray(points)
    except (TypeError, ValueError) as exc:
        raise not_numeric(exc) from None
    if raw.dtype.kind == "c":
        raise HeatcurvError(f"{name} must be real numbers, got complex ones ({raw.dtype})")
    if raw.dtype.kind == "b":
        raise HeatcurvError(f"{name} must be numbers, got booleans (a mask?)")
    try:
        return raw.astype(np.float64, copy=False)
    except (TypeError, ValueError) as exc:
        raise not_numeric(exc) from None


def row_hashes(points: np.ndarray) -> np.ndarray:
    """A 64-bit hash of the bits of each row, shape (n,), uint64: equal rows hash alike, whatever their order.

    A multiply-add of the three coordinates' bits, then an xor-shift; also the winding number's
    pseudo-random source rank (:func:`heatcurv.orient.enclosure.source_keys`).
    """
    bits = np.ascontiguousarray(points, dtype=np.float64).view(np.uint64)
    key = (bits * np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9], dtype=np.uint64)).sum(
        axis=1, dtype=np.uint64)
    key ^= key >> np.uint64(29)
    return key


def distinct_rows(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``points`` that first show each distinct value, and every row's distinct value.

    Rows are grouped by a 64-bit hash of their bits: sorting one integer per
    row takes a twentieth of what ``np.unique(axis=0)`` takes on the rows
    themselves (1.1 s for a million points), and only the rows whose hash
    repeats are compared. Different rows of one hash (odds of about ``n^2 /
    2^65``) fall back to ``np.unique``.

    Parameters
    ----------
    points : ndarray, shape (n, 3), float64
        No NaN; ``-0.0`` and ``0.0`` differ (add ``0.0`` first to merge them).

    Returns
    -------
    first : ndarray of int64, shape (m,)
        Increasing: the first row of each distinct value, in the order they
        first occur (``points[first]`` are the distinct rows).
    inverse : ndarray of int64, shape (n,)
        ``points[first][inverse] == points``.
    """
    n = points.shape[0]
    if n < 2:
        return np.arange(n), np.arange(n)
    key = row_hashes(points)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    starts = np.concatenate([[True], sorted_key[1:] != sorted_key[:-1]])
    if starts.all():
        return np.arange(n), np.arange(n)
    group = np.cumsum(starts) - 1  # per sorted row, its hash's group
    head = order[starts]  # per group, its first row (the sort is stable)
    repeats = np.flatnonzero(~starts)
    if not np.array_equal(points[order[repeats]], points[head[group[repeats]]]):
        _, head, group_of_row = np.unique(points, axis=0, return_index=True, return_inverse=True)
        group = group_of_row.reshape(-1)[order]
    rank = np.empty(head.size, dtype=np.int64)
    rank[np.argsort(head)] = np.arange(head.size)
    inverse = np.empty(n, dtype=np.int64)
    inverse[order] = rank[group]
    return np.sort(head), inverse


def bounding_box_frame(low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, float]:
    """The centring origin and length unit of a cloud with bounding box ``low``, ``high`` (shape (3,) each).

    Returns
    -------
    offset : ndarray, shape (3,)
        The box's centre, input units.
    unit : float
        The stages' length unit (:data:`UNIT_BAND`).

    Raises
    ------
    HeatcurvError
        If the extent is outside :data:`EXTENT_RANGE`.
    """
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    offset = 0.5 * low + 0.5 * high  # (low + high) / 2 overflows near the largest double
    with np.errstate(over="ignore"):  # a span beyond the largest double is inf, refused below
        unit = _length_unit(high - low)
    return offset, unit


def prepare_points(points, min_points: int = 7, frame=None) -> PreparedPoints:
    """Validate ``points``, centre them and merge exact duplicates.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Point coordinates in any length unit.
    min_points : int, optional
        The fewest distinct points the pipeline can work with (one point and
        the neighbours its fit needs).
    frame : heatcurv.choice.choices.CloudFrame, optional
        The whole cloud's frame, when ``points`` are a part of it (a tile): its
        origin and unit are used instead of this part's bounding box, so every
        part computes in the same coordinates.

    Returns
    -------
    PreparedPoints

    Raises
    ------
    HeatcurvError
        If the array does not have shape ``(n, 3)``, holds NaN or infinite
        values, has fewer than ``min_points`` distinct points, or its points
        all coincide or all lie on one line (no surface to measure).
    """
    arr = _as_float_array(points, "points")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise HeatcurvError(
            f"points must have shape (n, 3), got shape {arr.shape}; "
            "pass one row of x, y, z coordinates per point"
        )
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        rows = np.flatnonzero(bad)
        shown = ", ".join(str(r) for r in rows[:5]) + (", ..." if rows.size > 5 else "")
        raise HeatcurvError(
            f"points hold NaN or infinite coordinates in {rows.size} row(s) "
            f"(rows {shown}); remove or repair them first"
        )
    if arr.shape[0] == 0:
        raise HeatcurvError("points is empty: a point cloud needs at least a few points")

    low, high = arr.min(axis=0), arr.max(axis=0)
    if frame is None:
        offset, unit = bounding_box_frame(low, high)
    else:
        offset, unit = np.asarray(frame.offset, dtype=np.float64), float(frame.unit)
    centred = (arr - offset) / unit + 0.0  # + 0.0 turns -0.0 into 0.0: equal coordinates, equal bits
    first, inverse = distinct_rows(centred)
    distinct = centred if first.size == centred.shape[0] else centred[first]
    m = distinct.shape[0]
    if m == 1:
        raise HeatcurvError(
            f"all {arr.shape[0]} points coincide: there is no surface to measure"
        )
    if m < min_points:
        raise HeatcurvError(
            f"too few points: {m} distinct point(s), the neighbourhoods need at least {min_points}"
        )
    # Degeneracy: the cloud's extent along its second principal axis relative to the first.
    sing = np.linalg.svd(distinct - distinct.mean(axis=0), compute_uv=False)
    # rounding of the input coordinates themselves sets a floor (far-off scans)
    rounding = 100.0 * np.finfo(np.float64).eps * (float(np.abs(arr).max()) / unit) * np.sqrt(m)
    if sing[1] <= rounding and sing[1] > 1e-10 * sing[0]:
        raise HeatcurvError(
            f"all {m} distinct points lie on one line to within the rounding of their coordinates (they lie "
            f"{float(np.abs(arr).max()):.3g} from the origin and span {float(np.max(high - low)):.3g}): a surface "
            "needs points spread in two directions; if they are, subtract a nearby origin from the coordinates "
            "first (double precision cannot resolve the spread so far out)"
        )
    if sing[1] <= max(1e-10 * sing[0], rounding):
        raise HeatcurvError(
            f"all {m} distinct points lie on one line: a point cloud surface needs "
            "points spread in two directions"
        )
    return PreparedPoints(points=distinct, offset=offset, inverse=inverse, first=first, unit=unit)


def _length_unit(sides: np.ndarray) -> float:
    """The power of two the centred points are divided by (:data:`UNIT_BAND`), or an error.

    Parameters
    ----------
    sides : ndarray, shape (3,)
        Bounding-box sides of the cloud, input units (inf if they overflow).

    Raises
    ------
    HeatcurvError
        If the extent is outside :data:`EXTENT_RANGE` (a zero extent is left
        to the coincidence check).
    """
    extent = float(np.max(sides))
    if extent == 0.0:
        return 1.0
    low, high = EXTENT_RANGE
    if not low <= extent <= high:
        raise HeatcurvError(
            f"the cloud spans {extent:.3g} length units, outside the range heatcurv computes in "
            f"({low:g} to {high:g}): its areas or Gaussian curvatures would not fit in double precision; "
            "rescale the coordinates (e.g. to metres) first"
        )
    if UNIT_BAND[0] <= extent <= UNIT_BAND[1]:
        return 1.0
    return float(2.0 ** np.round(np.log2(extent)))


def prepare_normals(normals, prepared: PreparedPoints) -> np.ndarray:
    """Validate caller-given normals and reduce them to the distinct points.

    Parameters
    ----------
    normals : array_like, shape (n, 3)
        One normal per input row (need not be unit length).
    prepared : PreparedPoints
        The prepared points of the same input.

    Returns
    -------
    ndarray, shape (m, 3)
        Unit normals of the distinct points (the first input row of each).

    Raises
    ------
    HeatcurvError
        On a shape that does not match the points, non-finite or zero normals.
    """
    arr = _as_float_array(normals, "normals")
    if arr.shape != (prepared.n_input, 3):
        raise HeatcurvError(
            f"normals must have shape ({prepared.n_input}, 3) like the points, got {arr.shape}"
        )
    if not np.isfinite(arr).all():
        raise HeatcurvError("normals hold NaN or infinite values")
    arr = arr[prepared.first]
    length = np.linalg.norm(arr, axis=1)
    if np.any(length <= 0):
        raise HeatcurvError(
            f"{int(np.sum(length <= 0))} normal(s) have zero length; cannot orient curvature signs"
        )
    return arr / length[:, None]
