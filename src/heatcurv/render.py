"""Pictures of a point cloud coloured by a per-point field (curvature, area, features, ...).

:func:`render_field` draws the points as an orthographic 3-D scatter, as seen
by a camera looking along the cloud's thinnest direction, coloured by one
value per point, with a colour bar, and saves the figure (PNG, PDF, SVG, JPEG,
... by the file's extension). It is what ``heatcurv render`` and ``heatcurv
demo`` draw.

Drawing
-------
* **Colours.** The limits come from the data and are robust: the 2nd and
  98th percentiles of the values, so a few wild values at holes and borders
  do not wash the picture out; the colour bar's arrows say that values
  beyond them exist. A signed field (mean, Gaussian and principal
  curvatures, normal and direction components) whose values change sign
  (the 2nd percentile negative, the 98th positive) uses a diverging map
  (``"coolwarm"``: blue negative, grey zero, red positive) with limits
  symmetric about 0 (the larger magnitude of the two percentiles), so
  equal magnitudes get equal strength and zero is the neutral colour. A
  signed field of one sign (a sphere's or a torus's mean curvature, all
  positive) and the non-negative fields (area, feature score, spacing) use
  the sequential map (``"viridis"``, dark to light as the values grow, read
  alike by colour-blind viewers and in grey print) from the 2nd to the 98th
  percentile, so the whole bar shows the values' spread rather than half
  of it standing empty; the colour bar's numbers give the sign. Masks
  (``feature``, ``reliable``, ``border``) get two colours. The colour bar
  is labelled with the field and its unit (``1/m`` for curvature with
  ``length_unit="m"``, ``m²`` for area, ``degrees`` for feature scores).
  ``value_range`` fixes the limits (diverging if they hold both signs).
  Points whose value is NaN are drawn light grey.
* **View.** The camera looks along the smallest principal axis of the
  points (a scan is seen face-on, a terrain from above), from the side most
  normals face, with the cloud's vertical axis (``+y``, or ``+z`` for
  geographic data) up on the picture, in orthographic projection with
  equal scale on both screen axes. ``views = N`` draws N views side by side, the
  camera turned about the up axis by ``360 / N`` degrees each time (2: front
  and back; 4: every quarter turn); ``elevation`` tilts the camera up. The
  points are drawn from far to near, so near points cover far ones.
* **Shading.** Each point's colour is lit by a headlight slightly above and
  left of the camera (:data:`heatcurv.shading.AMBIENT` light plus Lambert's
  diffuse light, from the normals given, else from normals fitted to each
  point's nearest neighbours), as 3-D viewers light a surface: surfaces
  facing the viewer keep their colour, the outline and the lower right
  darken, so the shape reads. Lighting is two-sided (normals of either sign
  light alike). ``shade=False`` draws the flat colours of the colour bar.
* **Hidden points.** With normals given, the points facing away from the
  camera that lie behind a surface facing it (a point facing the camera
  within two disc diameters on the picture and more than
  :data:`heatcurv.shading.HIDDEN_DEPTH` diameters nearer: the far side of a
  closed object) are not drawn, so they cannot show through the gaps between
  the near side's discs; the back of an open scan, with nothing in front of
  it, is drawn. Normals of either orientation work: the sign that hides more
  is used. :mod:`heatcurv.shading` computes the lighting and the hidden
  points.
* **Points** are discs 1.2 (regular samples) to 2 (random samples) times as
  wide as the side of the surface area per point (from the distance to the
  8th nearest neighbour), so the surface looks closed even where a random
  sample leaves gaps (at most 80 pixels); each is drawn over a disc
  :data:`UNDERLAY` times wider, drawn first, that fills the last gaps with
  the colour of the surface around them. Above ``max_points`` a random
  (seeded) subset is drawn.

matplotlib is used through its object interface with the Agg canvas, never
``pyplot``: rendering changes no global state (an interactive session's
backend stays as it was) and needs no display.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import HeatcurvError
from .options import SEED_RANGE, Range, range_problem

# the lighting constants stay importable from here, where the pictures are described
from .shading import AMBIENT as AMBIENT
from .shading import HIDDEN_DEPTH as HIDDEN_DEPTH
from .shading import LIGHT as LIGHT
from .shading import estimated_normals, hidden_back_faces, shade_colours

__all__ = [
    "FIELD_STYLES",
    "FieldStyle",
    "Rendering",
    "camera_frames",
    "colour_limits",
    "field_style",
    "grey_unreliable",
    "render_field",
    "supported_picture_formats",
]

#: Colour map of signed fields (light grey at zero: visible on the white background).
DIVERGING_CMAP = "coolwarm"
#: Colour map of non-negative fields.
SEQUENTIAL_CMAP = "viridis"
#: Colours of a mask's False and True points.
MASK_COLOURS = ("#c8c8c8", "#d62728")
#: Colour of points whose value is NaN.
MISSING_COLOUR = "#bbbbbb"
#: Disc diameter on random samples, in units of the side of the surface area per point: discs
#: of this size cover 1 - exp(-pi 2^2 / 4) = 96 % of a surface sampled at random (more where it
#: is seen obliquely). Regular samples get smaller discs (:func:`_disc_diameter`).
DISC_FACTOR = 2.0
#: The points are drawn twice, far to near: first as discs this many times wider, then at their
#: size. The wide discs fill the gaps a random sample leaves between the discs (the surface, not
#: whatever is behind it, shows through them: coverage 1 - exp(-pi (1.75 x 2)^2 / 4) > 99.99 %).
UNDERLAY = 1.75


@dataclass(frozen=True)
class FieldStyle:
    """How a named field is labelled and coloured.

    Attributes
    ----------
    label : str
        What the field is, for the colour bar (``"mean curvature"``).
    unit : str
        Its unit, ``{L}`` standing for the length unit (``"1/{L}"``); empty
        for unitless fields.
    kind : {"signed", "sequential", "mask"} or None
        Diverging map centred at 0, sequential map, or two colours; None:
        decided from the values (signed if the robust range holds both signs).
    """

    label: str
    unit: str = ""
    kind: str | None = None

    def unit_text(self, length_unit: str = "length") -> str:
        """The unit with the length unit filled in (``"1/m"``), or ``""``."""
        return self.unit.replace("{L}", length_unit)

    def bar_label(self, length_unit: str = "length") -> str:
        """The colour bar's label: the field and its unit (``"mean curvature (1/m)"``), or the field alone."""
        unit = self.unit_text(length_unit)
        return f"{self.label} ({unit})" if unit else self.label


#: Styles of the fields heatcurv writes (``heatcurv compute``), by name.
FIELD_STYLES: dict[str, FieldStyle] = {
    "mean": FieldStyle("mean curvature", "1/{L}", "signed"),
    "gaussian": FieldStyle("Gaussian curvature", "1/{L}²", "signed"),
    "k1": FieldStyle("maximal principal curvature k1", "1/{L}", "signed"),
    "k2": FieldStyle("minimal principal curvature k2", "1/{L}", "signed"),
    "area": FieldStyle("area per point", "{L}²", "sequential"),
    "feature": FieldStyle("sharp feature", "", "mask"),
    "feature_score": FieldStyle("feature score (turning angle)", "degrees", "sequential"),
    "reliable": FieldStyle("reliable", "", "mask"),
    "border": FieldStyle("border point", "", "mask"),
    "spacing": FieldStyle("kernel spacing h", "{L}", "sequential"),
    "neighbours": FieldStyle("neighbours in the ball", "", "sequential"),
    "fit_radius": FieldStyle("radius of the fitted ball (per-point scale)", "{L}", "sequential"),
    "mean_se": FieldStyle("standard error of the mean curvature", "1/{L}", "sequential"),
    "gaussian_se": FieldStyle("standard error of the Gaussian curvature", "1/{L}²", "sequential"),
    "k1_se": FieldStyle("standard error of k1", "1/{L}", "sequential"),
    "k2_se": FieldStyle("standard error of k2", "1/{L}", "sequential"),
    "normal_se": FieldStyle("standard error of the normal", "degrees", "sequential"),
    "geodesic_distance": FieldStyle("geodesic distance", "{L}", "sequential"),
    **{f"n{a}": FieldStyle(f"normal, {a} component", "", "signed") for a in "xyz"},
    **{f"d1{a}": FieldStyle(f"principal direction d1, {a} component", "", "signed") for a in "xyz"},
    **{f"d2{a}": FieldStyle(f"principal direction d2, {a} component", "", "signed") for a in "xyz"},
    **{a: FieldStyle(f"{a} coordinate", "{L}", "sequential") for a in "xyz"},
}


def field_style(name) -> FieldStyle:
    """The style of field ``name``: from :data:`FIELD_STYLES`, else the name itself, kind from the data.

    A :class:`FieldStyle` given as ``name`` is returned as it is (a quantity heatcurv does not name).
    """
    if isinstance(name, FieldStyle):
        return name
    return FIELD_STYLES.get(name, FieldStyle(name))


@dataclass(frozen=True)
class Rendering:
    """What :func:`render_field` drew.

    Attributes
    ----------
    path : pathlib.Path
        The picture written.
    limits : tuple of float
        Colour-bar limits ``(low, high)``.
    kind : str
        ``"signed"``, ``"sequential"`` or ``"mask"``.
    drawn : int
        Points drawn (after dropping non-finite coordinates and subsampling;
        in each view but for its ``hidden`` ones).
    total : int
        Points given.
    size : tuple of int
        Picture size in pixels ``(width, height)`` (raster formats).
    shading : str
        ``"normals"`` (shaded from the normals given), ``"estimated normals"``
        (none given: shaded from normals fitted to the points' neighbours) or
        ``"flat"`` (``shade=False``).
    hidden : tuple of int
        Per view, the points not drawn because they face away from the camera
        behind a surface that faces it (only with normals given).
    label : str
        The colour bar's label, the field and its unit
        (``"mean curvature (1/mm)"``).
    """

    path: Path
    limits: tuple
    kind: str
    drawn: int
    total: int
    size: tuple
    shading: str = "flat"
    hidden: tuple = ()
    label: str = ""


def supported_picture_formats() -> tuple:
    """File extensions matplotlib can save to (``".png"``, ``".pdf"``, ``".svg"``, ...)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted("." + ext for ext in FigureCanvasBase.get_supported_filetypes()))


def _is_mask(values: np.ndarray) -> bool:
    finite = values[np.isfinite(values)]
    return values.dtype.kind == "b" or (finite.size > 0 and bool(np.all((finite == 0) | (finite == 1))))


def grey_unreliable(values: np.ndarray, reliable: np.ndarray) -> np.ndarray:
    """``values`` with the unreliable points' set to NaN, so that :func:`render_field` draws them grey.

    Parameters
    ----------
    values : ndarray, shape (n,)
    reliable : ndarray of bool, shape (n,)

    Returns
    -------
    ndarray, shape (n,), float
    """
    return np.where(np.asarray(reliable, dtype=bool), values, np.nan)


def colour_limits(values, kind: str | None = None, *, percentiles=(2.0, 98.0), value_range=None):
    """Colour limits and kind of a field: robust percentiles, symmetric about 0 when the values change sign.

    Parameters
    ----------
    values : array_like, shape (n,)
        The field (NaN values are ignored).
    kind : {"signed", "sequential", "mask"}, optional
        What the field is: ``"signed"`` a quantity of either sign (a
        curvature), ``"sequential"`` one to colour from low to high,
        ``"mask"`` two values. Default: ``"mask"`` for booleans and 0/1
        values, else ``"signed"``.
    percentiles : (float, float), optional
        Lower and upper percentile of the robust range.
    value_range : (float, float), optional
        Fixed limits instead of the percentiles.

    Returns
    -------
    low, high : float
        ``low < high``: the two percentiles of the values, or
        ``value_range``. A signed field whose robust range holds both signs
        gets ``-v, v``, ``v`` the larger magnitude of the two percentiles.
    kind : str
        ``"signed"`` (diverging colours, 0 at the centre) only for a signed
        field whose range holds both signs (``low < 0 < high``);
        ``"sequential"`` for a signed field of one sign (a sphere's mean
        curvature) as for non-negative fields; ``"mask"``.

    Raises
    ------
    HeatcurvError
        If no value is finite, or the percentiles or range are unusable.
    """
    values = np.asarray(values)
    numeric = values.astype(np.float64)
    finite = numeric[np.isfinite(numeric)]
    if finite.size == 0:
        raise HeatcurvError("the field has no finite values to colour by")
    if kind is None and _is_mask(values):
        kind = "mask"
    if kind == "mask":
        return -0.5, 1.5, "mask"
    if value_range is not None:
        low, high = (float(v) for v in value_range)
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise HeatcurvError(f"the colour range must be two finite numbers LOW < HIGH, got {low:g}, {high:g}")
        return low, high, "signed" if kind != "sequential" and low < 0 < high else "sequential"
    p_low, p_high = (float(p) for p in percentiles)
    if not 0 <= p_low < p_high <= 100:
        raise HeatcurvError(f"percentiles must satisfy 0 <= LOW < HIGH <= 100, got {p_low:g}, {p_high:g}")
    low, high = (float(v) for v in np.percentile(finite, [p_low, p_high]))
    if kind != "sequential" and low < 0 < high:  # the values change sign: 0 at the centre, equal magnitudes alike
        bound = max(-low, high)
        return -bound, bound, "signed"
    if not high > low:  # a constant field
        if low == 0 and kind != "sequential":  # a signed field that is zero: the diverging map's neutral colour
            return -1.0, 1.0, "signed"
        pad = abs(low) * 0.01 if low != 0 else 1.0
        low, high = low - pad, high + pad
    return low, high, "sequential"


def _unit(vector, name: str) -> np.ndarray:
    try:
        v = np.asarray(vector, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        v = np.empty(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or not np.linalg.norm(v) > 0:
        raise HeatcurvError(f"{name} must be 3 finite numbers, not all zero, got {vector!r}")
    return v / np.linalg.norm(v)


def _positive_sign(vector: np.ndarray) -> np.ndarray:
    """The vector or its opposite, whichever has a positive largest-magnitude component."""
    return vector if vector[np.argmax(np.abs(vector))] >= 0 else -vector


def camera_frames(
    points, views: int = 1, *, view=None, up=None, vertical: str = "y", elevation: float = 0.0, normals=None
):
    """Orthonormal screen frames ``(right, up, towards the camera)`` of the views of a cloud.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Finite coordinates.
    views : int, optional
        Number of views, the camera turned about the up axis by ``360 / views``
        degrees from one to the next.
    view : array_like, shape (3,), optional
        Direction from the cloud towards the camera of the first view.
        Default: the smallest principal axis, on the side most ``normals``
        face (or the side of its largest positive coordinate component).
    up : array_like, shape (3,), optional
        Screen up (made perpendicular to ``view``). Default: the coordinate
        axis ``vertical``, or if the camera looks (nearly) along it, the
        next of ``+y``, ``+z``, ``+x`` that it does not look along.
    vertical : {"y", "z", "x"}, optional
        The coordinate axis that points up in the cloud's convention: ``y``
        for most meshes and lab scans (the Stanford models), ``z`` for
        geographic data (LAS). A cloud seen from above (a terrain) gets
        ``+y`` up, north if ``y`` is northing.
    elevation : float, optional
        Camera tilt above the first view's horizontal plane, degrees in
        [-90, 90].
    normals : ndarray, shape (n, 3), optional
        Used only to choose the default side of the camera.

    Returns
    -------
    ndarray, shape (views, 3, 3)
        Row 0 screen right, row 1 screen up, row 2 towards the camera; right
        = up x towards (no mirror image). Screen coordinates of a point are
        ``frames[k] @ (p - centre)``.

    Raises
    ------
    HeatcurvError
        On a bad ``view``, ``up`` or ``elevation``, or ``up`` parallel to ``view``.
    """
    points = np.asarray(points, dtype=np.float64)
    _check_number("views", views)
    _check_number("elevation", elevation)
    views = int(views)
    centred = points - points.mean(axis=0)
    if centred.shape[0] > 100_000:  # the principal axes of a subset are as good
        centred = centred[np.random.default_rng(0).choice(centred.shape[0], 100_000, replace=False)]
    _, axes = np.linalg.eigh(centred.T @ centred)  # columns: smallest, middle, largest
    if view is None:
        toward = _positive_sign(axes[:, 0])
        if normals is not None:
            facing = np.sum(np.sign(np.asarray(normals, dtype=np.float64) @ toward))
            if facing < 0:
                toward = -toward
    else:
        toward = _unit(view, "view")
    if up is None:
        if vertical not in ("x", "y", "z"):
            raise HeatcurvError(f"vertical must be 'x', 'y' or 'z', got {vertical!r}")
        order = [vertical] + [a for a in "yzx" if a != vertical]
        basis = {a: np.eye(3)[k] for k, a in enumerate("xyz")}
        up_vector = next(basis[a] for a in order if abs(basis[a] @ toward) < 0.9)
    else:
        up_vector = _unit(up, "up")
    up_vector = up_vector - (up_vector @ toward) * toward
    if not np.linalg.norm(up_vector) > 1e-6:
        raise HeatcurvError("the up direction must not be parallel to the view direction")
    up_vector /= np.linalg.norm(up_vector)
    right = np.cross(up_vector, toward)
    tilt = np.radians(elevation)
    frames = np.empty((views, 3, 3))
    for k in range(views):  # a handful of views: not a per-point loop
        turn = 2.0 * np.pi * k / views
        t = np.cos(turn) * toward + np.sin(turn) * right
        t, u = np.cos(tilt) * t + np.sin(tilt) * up_vector, -np.sin(tilt) * t + np.cos(tilt) * up_vector
        frames[k] = np.stack([np.cross(u, t), u, t])
    return frames


def _grid(views: int, width: float, height: float, aspect: float = 1.0) -> tuple[int, int]:
    """Rows and columns of ``views`` panels drawing the cloud largest in a ``width x height`` area.

    ``aspect`` is the width / height of the cloud's picture in one view.
    """
    best = None
    for rows in range(1, views + 1):
        cols = -(-views // rows)
        if (rows - 1) * cols >= views:
            continue
        scale = min(width / cols / aspect, height / rows)  # height of the cloud in a panel
        if best is None or scale > best[0] * (1 + 1e-9):
            best = (scale, rows, cols)
    return best[1], best[2]


def _disc_diameter(points: np.ndarray) -> float:
    """Disc diameter, in length units, that makes the drawn points look like a closed surface.

    The side of the surface area per point is ``d_8 sqrt(pi / 8)``, with
    ``d_8`` the median distance to the 8th nearest neighbour (over up to
    20 000 query points): the disc of radius ``d_8`` holds 8 points. Regular
    samples (lattices, scans: the nearest neighbour is about half as far as
    the 8th) are covered by discs 1.2 times that side; random samples, which
    leave gaps (nearest neighbour 3.4 times closer than the 8th), need
    :data:`DISC_FACTOR` times it. The factor is interpolated between the two
    by that distance ratio. Returns 0 with fewer than 9 points.
    """
    from scipy.spatial import cKDTree

    if points.shape[0] < 9:
        return 0.0
    tree = cKDTree(points)
    query = points
    if points.shape[0] > 20_000:
        query = points[np.random.default_rng(1).choice(points.shape[0], 20_000, replace=False)]
    distance, _ = tree.query(query, k=9)
    eighth, nearest = float(np.median(distance[:, 8])), float(np.median(distance[:, 1]))
    side = eighth * np.sqrt(np.pi / 8.0)
    ratio = eighth / nearest if nearest > 0 else 3.4
    factor = float(np.interp(ratio, [2.0, 3.4], [1.2, DISC_FACTOR]))
    return factor * side


# ----------------------------------------------------------------------------- the steps of render_field


def _check_picture_path(path) -> tuple[Path, str]:
    """The picture's path and lower-case extension; an error on an unknown format or a missing directory."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in supported_picture_formats():
        raise HeatcurvError(
            f"cannot write {path}: unknown picture extension {ext or '(none)'!r}; "
            f"supported: {' '.join(supported_picture_formats())}"
        )
    if not path.parent.is_dir():
        raise HeatcurvError(f"cannot write {path}: the directory {path.parent} does not exist")
    return path, ext


#: The documented ranges of :func:`render_field`'s numbers (the command line's flags use the same).
PICTURE_RANGES: dict[str, Range] = {
    "views": Range(1, 36, True, "views side by side, turned 360/N degrees apart: 36 is every 10 degrees"),
    "dpi": Range(10, 2400, True, "the scale of the text (points per inch of the saved figure)"),
    "max_points": Range(1, 100_000_000, True, "points drawn; a picture of at most 10000x10000 has 1e8 pixels"),
    "point_size": Range(
        0.01, 1000.0, False, "disc diameter in pixels; the automatic one is 1-80, a picture side at most 10000",
    ),
    "elevation": Range(-90.0, 90.0, False, "an angle up from the horizon, in degrees"),
    "seed": SEED_RANGE,
}


def _check_number(name: str, value) -> None:
    """Raise the one-line :func:`heatcurv.options.range_problem` of ``value`` against :data:`PICTURE_RANGES`."""
    problem = range_problem(name, value, PICTURE_RANGES[name])
    if problem is not None:
        raise HeatcurvError(problem)


def _check_inputs(points, values, size, dpi, max_points) -> tuple[np.ndarray, np.ndarray, int, int]:
    """``(points, values, width, height)``: the arrays and the picture size, checked."""
    points = np.asarray(points, dtype=np.float64)
    values = np.asarray(values)
    if points.ndim != 2 or points.shape[1] != 3:
        raise HeatcurvError(f"points must have shape (n, 3), got {points.shape}")
    if values.shape != (points.shape[0],) or values.dtype.kind not in "biuf":
        raise HeatcurvError(f"values must be numbers of shape ({points.shape[0]},), got {values.dtype} {values.shape}")
    try:
        width, height = (float(v) for v in size)
    except (TypeError, ValueError):
        raise HeatcurvError(f"size must be two numbers (width, height) in pixels, got {size!r}") from None
    if not all(math.isfinite(v) and v.is_integer() and 100 <= v <= 10000 for v in (width, height)):
        raise HeatcurvError(f"the picture size must be 100-10000 whole pixels each way, got {width:g}x{height:g}")
    _check_number("dpi", dpi)
    _check_number("max_points", max_points)
    return points, values, int(width), int(height)


def _drawn_subset(points: np.ndarray, values: np.ndarray, normals, max_points: int, seed: int):
    """The points to draw: those with finite coordinates, a seeded random ``max_points`` of them if more.

    Returns ``(keep, xyz, shown, normals)``: the row numbers drawn (sorted),
    their coordinates, their values as float64, and their ``normals`` row for
    row, scaled to unit length (None if not given, or not of the points'
    shape; rows with a non-finite or zero normal are NaN).
    """
    drawable = np.isfinite(points).all(axis=1)
    if not drawable.any():
        raise HeatcurvError("no point has finite coordinates: nothing to draw")
    keep = np.flatnonzero(drawable)
    if keep.size > max_points:
        keep = np.sort(np.random.default_rng(seed).choice(keep, int(max_points), replace=False))
    xyz = points[keep]
    shown = values[keep].astype(np.float64)
    if normals is not None:
        normals = np.asarray(normals, dtype=np.float64)
        normals = normals[keep] if normals.shape == points.shape else None
        if normals is not None:
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                length = np.linalg.norm(normals, axis=1, keepdims=True)
                usable = np.isfinite(length) & (length > 0)
                normals = np.where(usable, normals / np.where(usable, length, 1.0), np.nan)
    return keep, xyz, shown, normals


def _colour_mapping(kind: str, low: float, high: float, cmap=None):
    """``(colour_map, norm)`` of a field of this kind and limits; NaN values get :data:`MISSING_COLOUR`.

    Masks get :data:`MASK_COLOURS`; signed fields ``cmap`` or :data:`DIVERGING_CMAP`
    (with 0 at the centre when the limits are not symmetric), others ``cmap``
    or :data:`SEQUENTIAL_CMAP`.
    """
    from matplotlib import colors as mcolors

    if kind == "mask":
        colour_map = mcolors.ListedColormap(list(MASK_COLOURS))
        norm = mcolors.BoundaryNorm([-0.5, 0.5, 1.5], 2)
    else:
        colour_map = cmap if cmap is not None else (DIVERGING_CMAP if kind == "signed" else SEQUENTIAL_CMAP)
        if isinstance(colour_map, str):
            import matplotlib

            try:
                colour_map = matplotlib.colormaps[colour_map]
            except KeyError:
                raise HeatcurvError(f"unknown colour map {colour_map!r}; see matplotlib's colormap reference") from None
        norm = (
            mcolors.TwoSlopeNorm(0.0, low, high)
            if kind == "signed" and low < 0 < high and not np.isclose(-low, high)
            else mcolors.Normalize(low, high)
        )
    return colour_map.with_extremes(bad=MISSING_COLOUR), norm


def _project(xyz: np.ndarray, frames: np.ndarray) -> tuple[list, list, np.ndarray]:
    """Screen coordinates of the views: ``(screens, middles, span)``.

    ``screens[k]`` holds, per point, right, up and depth towards the camera of
    view ``k`` (about the bounding box's centre); ``middles[k]`` is the centre
    of its picture; ``span`` the width and height every panel shows (the
    largest over the views, with a 2 % margin each side).
    """
    centre = 0.5 * (xyz.min(axis=0) + xyz.max(axis=0))
    screens = [(xyz - centre) @ frame.T for frame in frames]  # columns: right, up, depth to the camera
    middles = [0.5 * (screen[:, :2].min(axis=0) + screen[:, :2].max(axis=0)) for screen in screens]
    span = np.max([np.ptp(screen[:, :2], axis=0) for screen in screens], axis=0)
    span = np.maximum(span, 1e-9 * max(float(span.max()), 1e-300)) * 1.04  # 2 % margin each side
    return screens, middles, span


@dataclass(frozen=True)
class _Layout:
    """Where :func:`render_field` puts things, in inches from the figure's lower left corner.

    The title is on top, the panels (one scale for all views) centred below
    it in ``rows x cols``, the colour bar just right of them.
    """

    fig_w: float
    fig_h: float
    scale: float  # inches per length unit
    rows: int
    cols: int
    left: float  # left edge of the block of panels
    top: float  # top edge of the block of panels
    panel_w: float
    panel_h: float
    label_h: float  # space above each panel for its label (several views)
    gap: float
    block_w: float
    block_h: float
    area_h: float  # height available to the panels


def _layout(views: int, span: np.ndarray, width: int, height: int, dpi: int, title) -> _Layout:
    """The :class:`_Layout` of ``views`` panels showing ``span`` each, in a ``width x height`` pixel picture."""
    fig_w, fig_h = width / dpi, height / dpi
    margin, gap, bar_strip = 0.12, 0.12, 1.1
    title_h = 0.45 if title != "" else 0.1
    label_h = 0.28 if views > 1 else 0.0
    area_w, area_h = fig_w - 2 * margin - bar_strip, fig_h - margin - title_h
    rows, cols = _grid(views, area_w, area_h, aspect=float(span[0] / span[1]))
    scale = min(  # inches per length unit
        (area_w - (cols - 1) * gap) / (cols * span[0]), (area_h - rows * label_h - (rows - 1) * gap) / (rows * span[1])
    )
    scale = max(scale, 1e-6 / max(float(span.max()), 1e-300))
    panel_w, panel_h = scale * span[0], scale * span[1]
    block_w = cols * panel_w + (cols - 1) * gap
    block_h = rows * (panel_h + label_h) + (rows - 1) * gap
    left = margin + max(0.0, (area_w - block_w) / 2)  # the panels and the colour bar, centred
    top = fig_h - title_h - max(0.0, (area_h - block_h) / 2)
    return _Layout(
        fig_w=fig_w, fig_h=fig_h, scale=scale, rows=rows, cols=cols, left=left, top=top, panel_w=panel_w,
        panel_h=panel_h, label_h=label_h, gap=gap, block_w=block_w, block_h=block_h, area_h=area_h,
    )


def _add_panels(fig, layout: _Layout, views: int, middles: list, span: np.ndarray) -> list:
    """One axes per view, without axes lines, each showing ``span`` about its ``middles[k]``; labelled if several."""
    fig_w, fig_h = layout.fig_w, layout.fig_h
    axes = []
    for k in range(views):
        row, col = divmod(k, layout.cols)
        x0 = layout.left + col * (layout.panel_w + layout.gap)
        y0 = layout.top - row * (layout.panel_h + layout.label_h + layout.gap) - layout.label_h - layout.panel_h
        ax = fig.add_axes((x0 / fig_w, y0 / fig_h, layout.panel_w / fig_w, layout.panel_h / fig_h))
        ax.set_xlim(middles[k][0] - span[0] / 2, middles[k][0] + span[0] / 2)
        ax.set_ylim(middles[k][1] - span[1] / 2, middles[k][1] + span[1] / 2)
        ax.set_axis_off()
        if views > 1:
            ax.set_title(f"turned {360 * k / views:.0f}°", fontsize="small")
        axes.append(ax)
    return axes


def _add_colour_bar(fig, layout: _Layout, colour_map, norm, shown, low, high, kind: str, label: str) -> None:
    """The colour bar right of the panels, labelled; arrows where values lie beyond the limits."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import TwoSlopeNorm

    bar_h = min(max(layout.block_h * 0.9, min(2.0, layout.area_h)), layout.area_h)
    bar_x = layout.left + layout.block_w + 0.2
    bar_y = layout.top - layout.block_h / 2 - bar_h / 2
    bar_axes = fig.add_axes((bar_x / layout.fig_w, bar_y / layout.fig_h, 0.16 / layout.fig_w, bar_h / layout.fig_h))
    finite_values = shown[np.isfinite(shown)]
    if kind == "mask":
        extend = "neither"
    else:
        below, above = bool(np.any(finite_values < low)), bool(np.any(finite_values > high))
        extends = {(False, False): "neither", (True, False): "min", (False, True): "max", (True, True): "both"}
        extend = extends[(below, above)]
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=colour_map), cax=bar_axes, extend=extend)
    bar.set_label(label)
    if kind == "mask":
        bar.set_ticks([0, 1], labels=["no", "yes"])
    elif isinstance(norm, TwoSlopeNorm):
        bar.set_ticks([low, low / 2, 0.0, high / 2, high])


def _add_title(fig, layout: _Layout, heading: str) -> None:
    """The figure's title, centred at the top (none if ``heading`` is empty)."""
    if heading:
        fig.text(0.5, 1.0 - 0.12 / layout.fig_h, heading, ha="center", va="top", fontsize="large")


def _disc_pixels(xyz: np.ndarray, point_size, scale: float, dpi: int, disc: float | None = None) -> float:
    """Disc diameter in pixels: ``point_size``, else ``disc`` (default :func:`_disc_diameter`) at the scale (1-80)."""
    if point_size is not None:
        return float(point_size)
    if disc is None:
        disc = _disc_diameter(xyz)
    return float(np.clip(disc * scale * dpi, 1.0, 80.0)) if disc > 0 else 3.0


def _paint(axes: list, screens: list, colours: list, diameter: float, dpi: int, shown: list) -> None:
    """The points as discs of ``diameter`` pixels in each view's axes, drawn far to near (rasterised).

    ``colours[k]`` are the RGBA colours of view ``k``, ``shown[k]`` the mask
    of its points drawn.
    """
    for ax, screen, rgba, drawn in zip(axes, screens, colours, shown):
        rows = np.flatnonzero(drawn)
        order = rows[np.argsort(screen[rows, 2], kind="stable")]
        for size in (UNDERLAY * diameter, diameter):
            ax.scatter(
                screen[order, 0], screen[order, 1], s=(size * 72.0 / dpi) ** 2, c=rgba[order],
                marker="o", linewidths=0, rasterized=True,
            )


def _save(fig, path: Path, ext: str, dpi: int) -> None:
    """Save the figure in the format of ``ext`` through a temporary file (no partial picture on failure)."""
    from .io.atomic import atomic_write

    def save(stream):
        fig.savefig(stream, format=ext[1:], dpi=dpi, facecolor="white")

    try:
        atomic_write(path, save)
    except OSError as exc:
        raise HeatcurvError(f"cannot write {path}: {exc.strerror or exc}") from None


def render_field(
    points,
    values,
    path,
    *,
    field: str = "mean",
    views: int = 1,
    size=(1600, 1000),
    dpi: int = 150,
    value_range=None,
    percentiles=(2.0, 98.0),
    cmap=None,
    max_points: int = 200_000,
    point_size: float | None = None,
    title: str | None = None,
    length_unit: str = "length",
    normals=None,
    view=None,
    up=None,
    vertical: str = "y",
    elevation: float = 0.0,
    seed: int = 0,
    shade: bool = True,
) -> Rendering:
    """Draw a point cloud coloured by a per-point field and save the picture.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Coordinates; rows with NaN or infinite coordinates are not drawn.
    values : array_like, shape (n,)
        The field, one value per point (NaN: drawn light grey).
    path : str or os.PathLike
        The picture; its extension picks the format (``.png``, ``.pdf``,
        ``.svg``, ``.jpg``, ... see :func:`supported_picture_formats`). It is
        written to a temporary file first and then renamed, so a failure
        leaves no partial picture.
    field : str or FieldStyle, optional
        The field's name: picks the label, unit and colour map
        (:data:`FIELD_STYLES`; other names: labelled by the name, a diverging
        map if the values hold both signs). A :class:`FieldStyle` labels
        any other quantity with its unit
        (``FieldStyle("temperature", "K")``).
    views : int, optional
        Views side by side, the camera turned by ``360 / views`` degrees
        about the up axis each time.
    size : (int, int), optional
        Picture width and height in pixels (100-10000).
    dpi : int, optional
        Dots per inch: the scale of text and the size in inches of vector
        formats (``size / dpi``).
    value_range : (float, float), optional
        Colour limits; default from ``percentiles``.
    percentiles : (float, float), optional
        Robust colour range, see :func:`colour_limits`.
    cmap : str or matplotlib colormap, optional
        Overrides the field's colour map.
    max_points : int, optional
        Draw a random subset of this many points from larger clouds.
    point_size : float, optional
        Disc diameter in pixels; default 1.2 to 2 times the side of the
        surface area per point, so the discs cover the surface.
    title : str, optional
        Figure title; default the field's label.
    length_unit : str, optional
        Name of the length unit in the colour bar's label, which carries the
        field's unit: ``"m"`` gives ``mean curvature (1/m)``, ``area (m²)``.
    normals : array_like, shape (n, 3), optional
        Surface normals (any length, either orientation): they shade the
        points, hide the points facing away from the camera behind the near
        side, and choose which side of the cloud the default camera is on.
        Without them the points are shaded from normals fitted to their
        neighbours and none are hidden.
    view, up, vertical, elevation
        Camera, see :func:`camera_frames`.
    seed : int, optional
        Seed of the subset drawn from large clouds.
    shade : bool, optional
        Light the points (ambient and diffuse light from slightly above left
        of the camera), so the shape reads; False draws the flat colours of
        the colour bar. Points facing away are hidden either way.

    Returns
    -------
    Rendering

    Raises
    ------
    HeatcurvError
        On arrays of the wrong shape, no finite point or value, bad options,
        an unsupported extension, or a file that cannot be written.

    Examples
    --------
    >>> import heatcurv, tempfile, os
    >>> from heatcurv.render import render_field
    >>> sphere = heatcurv.surfaces.Sphere().sample(500, "fibonacci")
    >>> out = os.path.join(tempfile.mkdtemp(), "sphere.png")
    >>> render_field(sphere.points, sphere.points[:, 2], out, field="height", size=(400, 300)).size
    (400, 300)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path, ext = _check_picture_path(path)
    points, values, width, height = _check_inputs(points, values, size, dpi, max_points)
    if point_size is not None:
        _check_number("point_size", point_size)
    _check_number("seed", seed)
    style = field_style(field)
    low, high, kind = colour_limits(values, style.kind, percentiles=percentiles, value_range=value_range)
    keep, xyz, shown, normals = _drawn_subset(points, values, normals, max_points, seed)
    frames = camera_frames(
        xyz, views, view=view, up=up, vertical=vertical, elevation=elevation,
        normals=None if normals is None else normals[np.isfinite(normals).all(axis=1)],
    )
    colour_map, norm = _colour_mapping(kind, low, high, cmap)
    rgba = colour_map(norm(np.ma.masked_invalid(shown)))

    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor="white")
    FigureCanvasAgg(fig)
    screens, middles, span = _project(xyz, frames)
    layout = _layout(views, span, width, height, dpi, title)
    # discs: a fixed share of the surface area per point, in pixels; the panels widened so that the
    # wide discs of the outline (UNDERLAY) are drawn whole
    disc = None if point_size is not None else _disc_diameter(xyz)
    diameter = _disc_pixels(xyz, point_size, layout.scale, dpi, disc)
    span = span + UNDERLAY * diameter / (layout.scale * dpi)
    layout = _layout(views, span, width, height, dpi, title)
    diameter = _disc_pixels(xyz, point_size, layout.scale, dpi, disc)
    axes = _add_panels(fig, layout, views, middles, span)
    label = style.bar_label(length_unit)
    _add_colour_bar(fig, layout, colour_map, norm, shown, low, high, kind, label)
    _add_title(fig, layout, title if title is not None else style.label)
    lit, shading = normals, "normals"
    if not shade:
        lit, shading = None, "flat"
    elif lit is None:
        lit, shading = estimated_normals(xyz), "estimated normals"
    colours, drawn, hidden = [], [], []
    for frame, screen in zip(frames, screens):
        behind = np.zeros(xyz.shape[0], dtype=bool)
        if normals is not None:
            behind = hidden_back_faces(screen, normals @ frame[2], diameter / (layout.scale * dpi))
        drawn.append(~behind)
        hidden.append(int(behind.sum()))
        colours.append(rgba if lit is None else shade_colours(rgba, lit @ frame.T))
    _paint(axes, screens, colours, diameter, dpi, drawn)
    _save(fig, path, ext, dpi)
    return Rendering(
        path=path, limits=(float(low), float(high)), kind=kind, drawn=int(keep.size), total=int(points.shape[0]),
        size=(width, height), shading=shading if lit is not None else "flat", hidden=tuple(hidden), label=label,
    )
