"""Interactive views of a point cloud: one self-contained HTML page drawn with WebGL.

:func:`write_view` writes a single ``.html`` file holding the points, their
scalar fields and a small WebGL point renderer, so that the cloud can be
turned, zoomed and coloured by any of its fields in a web browser, with
nothing fetched from the network (the page's Content-Security-Policy forbids
it: everything it uses is inline). It is what ``heatcurv view`` writes.

The page
--------
* **Colours** follow :mod:`heatcurv.render`: the same colour maps
  (diverging for signed fields whose values change sign, sequential
  otherwise, two colours for masks)
  and the same robust limits (:func:`heatcurv.render.colour_limits`, the 2nd
  and 98th percentiles), computed here from every point of the field. Points
  whose value is NaN, and unreliable points (``reliable`` given) in the
  fields that mark them, are grey; a menu shows unreliable points grey,
  coloured or not at all.
* **Shading**: with normals, each point is lit from the camera (the absolute
  cosine of its normal to the viewing direction, so inconsistent
  orientations shade alike); without, the colours are flat.
* **Camera**: orthographic, first looking along the cloud's thinnest
  direction (:func:`heatcurv.render.camera_frames`, as the pictures do). Drag
  to turn, shift-drag or right-drag to move, the wheel to zoom about the
  pointer, double-click or ``R`` to go back to the first view. The points
  are discs as wide as the surface area per point, hidden behind nearer ones
  (a depth buffer); a slider scales them.
* **Field**: a menu of every field; the page address may name the first one
  shown (``view.html#field=k1``), and changing it updates the address.

Data
----
The page embeds the data as base64 little-endian arrays in a JSON block
(``<script type="application/json" id="heatcurv-data">``): coordinates as
float32 offsets from the bounding box's centre (kept in float64), so that
georeferenced coordinates keep their precision; each field as float32;
normals as three int8 per point (shading needs no more); the reliable mask
as uint8. A float array ``a`` is stored as ``a * 2**-e`` with a power of two
``e`` (0 unless the values would overflow or underflow float32; the
decoded values are ``stored * 2**e``). A point takes about 21 bytes of the
page with normals and the mask, and 5.3 more per field (base64 is 4/3 of the
bytes); above ``max_points`` a seeded random subset is embedded and the page
says so. Browsers cannot hold a string of more than about 2**29 characters,
so a data block beyond that is refused (:data:`MAX_DATA_CHARS`).
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import HeatcurvError
from .io.atomic import atomic_write, check_writable
from .options import range_problem
from .render import (
    DIVERGING_CMAP,
    MASK_COLOURS,
    MISSING_COLOUR,
    PICTURE_RANGES,
    SEQUENTIAL_CMAP,
    camera_frames,
    colour_limits,
    field_style,
)

__all__ = ["DEFAULT_MAX_POINTS", "View", "write_view", "page_data"]

#: Points embedded at most by default: a million points with the 15 fields ``heatcurv compute`` writes
#: make a page of about 100 MB, which a browser opens in seconds; beyond, a seeded random subset is shown.
DEFAULT_MAX_POINTS = 1_000_000
#: Disc diameter in units of the side of the surface area per point: discs this wide cover
#: 1 - exp(-pi 2.5^2 / 4) = 99 % of a surface sampled at random (the page's slider scales them).
DISC_FACTOR = 2.5
#: Extensions of the page.
HTML_EXTENSIONS = (".html", ".htm")
#: Float32 keeps seven digits of values whose magnitude lies well inside its range; beyond these powers
#: of two a field is stored scaled (see the module's notes).
_SAFE_EXPONENT = 100
#: The longest string a browser's JavaScript can hold (V8, Chromium's engine: 2**29 - 24 characters);
#: the page's data block is one.
MAX_DATA_CHARS = 2**29 - 24
#: The id of the JSON block holding the data.
DATA_ID = "heatcurv-data"


@dataclass(frozen=True)
class View:
    """What :func:`write_view` wrote.

    Attributes
    ----------
    path : pathlib.Path
        The page.
    field : str
        The field shown first.
    fields : tuple of str
        Every field of the page's menu, in its order.
    shown : int
        Points embedded (finite coordinates, at most ``max_points``).
    total : int
        Points given.
    limits : dict of str to tuple
        ``(low, high, kind)`` of each field's colours, or None for a field
        without a finite value (drawn grey).
    size : int
        Size of the page in bytes.
    """

    path: Path
    field: str
    fields: tuple
    shown: int
    total: int
    limits: dict
    size: int


def _pack(values: np.ndarray) -> dict:
    """``{"data": base64 of float32 little endian, "exponent": e}`` with ``values = stored * 2**e``."""
    values = np.asarray(values, dtype=np.float64)
    finite = np.abs(values[np.isfinite(values)])
    exponent = 0
    if finite.size and finite.max() > 0:
        largest = math.frexp(float(finite.max()))[1]
        smallest = math.frexp(float(finite[finite > 0].min()))[1]
        if largest > _SAFE_EXPONENT or smallest < -_SAFE_EXPONENT:
            exponent = largest
    stored = np.ldexp(values, -exponent).astype("<f4")
    return {"data": base64.b64encode(stored.tobytes()).decode("ascii"), "exponent": exponent}


def _bytes(values: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(values, dtype=dtype).tobytes()).decode("ascii")


def _hex(colour) -> str:
    from matplotlib import colors as mcolors

    return mcolors.to_hex(colour)


def _colour_table(name: str) -> str:
    """256 RGB entries of a matplotlib colour map, base64 uint8."""
    import matplotlib

    rgb = matplotlib.colormaps[name](np.linspace(0.0, 1.0, 256))[:, :3]
    return _bytes(np.round(rgb * 255), "u1")


def _check_points(points) -> np.ndarray:
    try:
        points = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise HeatcurvError("points must be numbers of shape (n, 3)") from None
    if points.ndim != 2 or points.shape[1] != 3:
        raise HeatcurvError(f"points must have shape (n, 3), got {points.shape}")
    if points.shape[0] == 0:
        raise HeatcurvError("no points to show")
    return points


def _check_fields(fields, n: int) -> dict:
    """The fields as float64 arrays of shape (n,); an (n, 3) field ``d1`` becomes ``d1x d1y d1z``."""
    checked = {}
    for name, values in (fields or {}).items():
        values = np.asarray(values)
        if values.dtype.kind not in "biuf":
            raise HeatcurvError(f"field {name!r} must hold numbers, got {values.dtype}")
        if values.shape == (n, 3):
            for k, axis in enumerate("xyz"):
                checked[f"{name}{axis}"] = values[:, k].astype(np.float64)
        elif values.shape == (n,):
            checked[str(name)] = values.astype(np.float64)
        else:
            raise HeatcurvError(f"field {name!r} must have shape ({n},) or ({n}, 3), got {values.shape}")
    return checked


def _check_optional(values, n: int, shape: tuple, what: str):
    if values is None:
        return None
    values = np.asarray(values)
    if values.shape != shape or values.dtype.kind not in "biuf":
        raise HeatcurvError(f"{what} must be numbers of shape {shape}, got {values.dtype} {values.shape}")
    return values


def _shown_rows(points: np.ndarray, max_points: int, seed: int) -> np.ndarray:
    """Rows with finite coordinates; a seeded random ``max_points`` of them (sorted) if more."""
    rows = np.flatnonzero(np.isfinite(points).all(axis=1))
    if rows.size == 0:
        raise HeatcurvError(f"none of the {points.shape[0]} points has finite coordinates: nothing to show")
    if rows.size > max_points:
        rows = np.sort(np.random.default_rng(seed).choice(rows, int(max_points), replace=False))
    return rows


def _disc_diameter(xyz: np.ndarray, *, queries: int = 20_000, seed: int = 0) -> float:
    """Disc diameter (length units): :data:`DISC_FACTOR` times the side of the area per point.

    The side is ``d_8 sqrt(pi / 8)``, ``d_8`` the median distance to the 8th
    nearest neighbour over up to ``queries`` random points; 1 % of the
    bounding box's diagonal for clouds too small or too degenerate for it.
    """
    from scipy.spatial import cKDTree

    diagonal = float(np.linalg.norm(np.ptp(xyz, axis=0)))
    fallback = 0.01 * diagonal if diagonal > 0 else 1.0
    if xyz.shape[0] < 10:
        return fallback
    query = xyz
    if xyz.shape[0] > queries:
        query = xyz[np.random.default_rng(seed).choice(xyz.shape[0], queries, replace=False)]
    distance, _ = cKDTree(xyz).query(query, k=9)
    d8 = float(np.median(distance[:, 8]))
    return DISC_FACTOR * d8 * math.sqrt(math.pi / 8.0) if d8 > 0 else fallback


def _check_size(count: int, fields: int, normals: bool, reliable: bool) -> None:
    """Refuse a data block longer than :data:`MAX_DATA_CHARS` (base64: 4 characters per 3 bytes)."""
    per_point = 4 / 3 * (12 + 4 * fields + (3 if normals else 0) + (1 if reliable else 0))
    if count * per_point > MAX_DATA_CHARS:
        fitting = int(0.95 * MAX_DATA_CHARS / per_point)
        raise HeatcurvError(
            f"{count} points with {fields} field(s) make a page of about {count * per_point / 1e6:.0f} MB, more "
            f"than a browser can read (about {MAX_DATA_CHARS / 1e6:.0f} MB); show at most about {fitting} points "
            "(max_points, on the command line --max-points) or fewer fields (--fields)"
        )


def _limits(values: np.ndarray, name: str, percentiles) -> tuple | None:
    """``(low, high, kind)`` of a field's colours, None if it has no finite value."""
    if not np.isfinite(values).any():
        return None
    low, high, kind = colour_limits(values, field_style(name).kind, percentiles=percentiles)
    return float(low), float(high), kind


def _choose_field(field, names: list, fields: dict, vertical: str) -> str:
    if field is None:
        if "mean" in names:
            return "mean"
        return names[0] if fields or vertical not in names else vertical
    if field not in names:
        raise HeatcurvError(f"no field {field!r} to show; the fields are {', '.join(names)}")
    return field


def page_data(
    points, fields, normals=None, *, field=None, reliable=None, grey_unreliable=None, coordinates=True,
    max_points: int = DEFAULT_MAX_POINTS, seed: int = 0, percentiles=(2.0, 98.0), length_unit: str = "length",
    vertical: str = "y", title: str | None = None, note: str | None = None,
) -> dict:
    """The JSON-ready data block of a view page; the parameters are those of :func:`write_view`.

    Returns
    -------
    dict
        ``count``, ``total``, ``centre``, ``positions`` (packed float32
        offsets from ``centre``), ``radius``, ``frame`` (3 rows: screen
        right, up, towards the camera), ``disc`` (diameter, length units),
        ``normals`` (base64 int8 or None), ``reliable`` (base64 uint8 or
        None), ``fields`` (a list of ``{name, label, kind, low, high, grey}``
        with ``values`` (packed float32) or ``axis`` (a coordinate)),
        ``field``, ``colours`` (tables and grey), ``title`` and ``notes``.
    """
    points = _check_points(points)
    n = points.shape[0]
    fields = _check_fields(fields, n)
    normals = _check_optional(normals, n, (n, 3), "normals")
    reliable = _check_optional(reliable, n, (n,), "reliable")
    for name, value in (("max_points", max_points), ("seed", seed)):
        problem = range_problem(name, value, PICTURE_RANGES[name])
        if problem is not None:
            raise HeatcurvError(problem)
    names = list(fields) + ([a for a in "xyz" if a not in fields] if coordinates else [])
    if not names:
        raise HeatcurvError("no field to colour by: give fields, or coordinates=True")
    field = _choose_field(field, names, fields, vertical)
    reliable = None if reliable is None else np.asarray(reliable) != 0
    grey = set(fields) - {"reliable"} if grey_unreliable is None else set(grey_unreliable)

    rows = _shown_rows(points, max_points, seed)
    _check_size(rows.size, len(fields), normals is not None, reliable is not None)
    xyz = points[rows]
    centre = (xyz.min(axis=0) + xyz.max(axis=0)) / 2.0
    offsets = xyz - centre
    radius = float(np.sqrt((offsets**2).sum(axis=1).max()))
    shown_normals = None if normals is None else np.asarray(normals, dtype=np.float64)[rows]
    facing = None
    if shown_normals is not None:
        length = np.linalg.norm(shown_normals, axis=1)
        usable = np.isfinite(length) & (length > 0)
        unit = np.zeros_like(shown_normals)
        unit[usable] = shown_normals[usable] / length[usable, None]
        shown_normals = np.round(unit * 127.0).astype(np.int8)
        facing = unit[usable] if usable.any() else None
    frame = camera_frames(xyz, 1, vertical=vertical, normals=facing)[0]

    entries = []
    finite_rows = np.isfinite(points).all(axis=1)
    for name in names:
        style = field_style(name)
        entry = {"name": name, "label": style.bar_label(length_unit),
                 "grey": reliable is not None and name in grey}
        if name in fields:
            values = fields[name]
            entry["values"] = _pack(values[rows])
        else:
            values = points[:, "xyz".index(name)]
            entry["axis"] = "xyz".index(name)
        counted = values[finite_rows]
        if entry["grey"]:
            counted = np.where(reliable[finite_rows], counted, np.nan)
        limits = _limits(counted, name, percentiles)
        entry.update(dict(zip(("low", "high", "kind"), limits)) if limits else {"low": None, "high": None,
                                                                               "kind": "none"})
        entries.append(entry)

    notes = []
    finite_count = int(finite_rows.sum())
    if rows.size < finite_count:
        notes.append(f"Showing a random {rows.size:,} of the {finite_count:,} points.")
    if finite_count < n:
        notes.append(f"{n - finite_count:,} point(s) without finite coordinates are not shown.")
    if note:
        notes.append(note)
    return {
        "count": int(rows.size), "total": n, "centre": centre.tolist(), "positions": _pack(offsets),
        "radius": radius if radius > 0 else 1.0, "frame": frame.tolist(), "disc": _disc_diameter(xyz),
        "normals": None if shown_normals is None else _bytes(shown_normals, "i1"),
        "reliable": None if reliable is None else _bytes(reliable[rows], "u1"),
        "fields": entries, "field": field, "title": title or "heatcurv view", "notes": notes,
        "colours": {"signed": _colour_table(DIVERGING_CMAP), "sequential": _colour_table(SEQUENTIAL_CMAP),
                    "mask": [_hex(c) for c in MASK_COLOURS], "missing": _hex(MISSING_COLOUR)},
    }


def _page(data: dict) -> str:
    """The HTML page of a data block: the template with the data, title and script inlined."""
    folder = resources.files("heatcurv.data")
    template = folder.joinpath("viewer.html").read_text(encoding="utf-8")
    script = folder.joinpath("viewer.js").read_text(encoding="utf-8")
    # JSON inside <script>: "</" would end the element, "<!--" start a comment; escaped, JSON.parse reads the same
    block = json.dumps(data, allow_nan=False, separators=(",", ":"))
    block = block.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
    parts = {"TITLE": html.escape(data["title"]), "SCRIPT": script.replace("</script", "<\\/script"),
             "DATA_ID": DATA_ID, "DATA": block}
    return re.sub(r"%(TITLE|SCRIPT|DATA_ID|DATA)%", lambda match: parts[match[1]], template)


def write_view(
    points, fields, path, normals=None, *, field=None, reliable=None, grey_unreliable=None, coordinates=True,
    max_points: int = DEFAULT_MAX_POINTS, seed: int = 0, percentiles=(2.0, 98.0), length_unit: str = "length",
    vertical: str = "y", title: str | None = None, note: str | None = None,
) -> View:
    """Write an interactive view of a point cloud: one self-contained HTML file (WebGL).

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Coordinates; rows with NaN or infinite coordinates are left out.
    fields : dict of str to array_like, shape (n,) or (n, 3)
        The scalar fields of the menu, in this order; an (n, 3) field ``d1``
        gives ``d1x d1y d1z``. Names of :data:`heatcurv.render.FIELD_STYLES`
        get their label, unit and colour map; others are labelled by their
        name and coloured as their values say (diverging if of both signs).
    path : str or os.PathLike
        The page, ``.html`` or ``.htm``; written to a temporary file first and
        then renamed, so a failure leaves no partial page.
    normals : array_like, shape (n, 3), optional
        Shade the points (a light at the camera); also choose the first
        view's side. Any length; NaN or zero rows are not shaded.
    field : str, optional
        The field shown first. Default: ``mean`` if given, else the first
        given, else the ``vertical`` coordinate.
    reliable : array_like of bool, shape (n,), optional
        heatcurv's ``reliable`` mask: the other points are grey (or, from the
        page's menu, coloured or hidden) in the fields of ``grey_unreliable``
        and left out of their colour limits.
    grey_unreliable : collection of str, optional
        The fields whose unreliable points are grey. Default: every field but
        ``reliable`` itself.
    coordinates : bool, optional
        Also offer the coordinates ``x``, ``y``, ``z`` as fields (computed in
        the page from the embedded points: they cost no space).
    max_points : int, optional
        Embed a seeded random subset of this many points from larger clouds
        (1 to 1e8); the page says so.
    seed : int, optional
        Seed of that subset.
    percentiles : (float, float), optional
        Robust colour range, see :func:`heatcurv.render.colour_limits`.
    length_unit : str, optional
        Name of the length unit in the labels (``"m"`` gives ``1/m``).
    vertical : {"y", "z", "x"}, optional
        The cloud's up axis, for the first view (``"z"`` for geographic data).
    title : str, optional
        Page title (default ``heatcurv view``).
    note : str, optional
        A line shown under the title.

    Returns
    -------
    View

    Raises
    ------
    HeatcurvError
        On no points or none with finite coordinates, arrays of the wrong
        shape or type, an unknown ``field``, bad ``max_points`` or
        ``percentiles``, an extension other than ``.html``/``.htm``, or a
        file that cannot be written.

    Examples
    --------
    >>> import heatcurv, tempfile, os
    >>> from heatcurv.view import write_view
    >>> points = heatcurv.surfaces.Sphere().sample(2000, "fibonacci").points
    >>> res = heatcurv.estimate(points)
    >>> out = os.path.join(tempfile.mkdtemp(), "sphere.html")
    >>> view = write_view(points, {"mean": res.mean, "area": res.area}, out, res.normals,
    ...                   reliable=res.reliable)
    >>> view.field, view.fields, view.shown
    ('mean', ('mean', 'area', 'x', 'y', 'z'), 2000)
    """
    path = Path(path)
    if path.suffix.lower() not in HTML_EXTENSIONS:
        raise HeatcurvError(f"cannot write {path}: a view is an HTML page, give a name ending in .html")
    check_writable(path)
    data = page_data(
        points, fields, normals, field=field, reliable=reliable, grey_unreliable=grey_unreliable,
        coordinates=coordinates, max_points=max_points, seed=seed, percentiles=percentiles,
        length_unit=length_unit, vertical=vertical, title=title, note=note,
    )
    encoded = _page(data).encode("utf-8")
    try:
        atomic_write(path, lambda stream: stream.write(encoded))
    except OSError as exc:
        raise HeatcurvError(f"cannot write {path}: {exc.strerror or exc}") from exc
    limits = {e["name"]: (None if e["kind"] == "none" else (e["low"], e["high"], e["kind"])) for e in data["fields"]}
    return View(path=path, field=data["field"], fields=tuple(e["name"] for e in data["fields"]),
                shown=data["count"], total=data["total"], limits=limits, size=len(encoded))
