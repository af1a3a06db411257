"""Shared by the format modules: the :class:`PointCloud` record, property-name roles, errors.

Holds the name aliases that give a column its role (coordinate, normal, colour),
the one-line error helpers, the colour conversion, the assembly of a
:class:`PointCloud` from named columns, and the validated record of what
:func:`heatcurv.io.write_points` writes (``_Output``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import HeatcurvError

# canonical name (lower case, alphanumerics only) -> role
_ALIASES = {
    "x": ("x",),
    "y": ("y",),
    "z": ("z",),
    "nx": ("nx", "normalx", "normx"),
    "ny": ("ny", "normaly", "normy"),
    "nz": ("nz", "normalz", "normz"),
    "red": ("red", "r", "diffusered"),
    "green": ("green", "g", "diffusegreen"),
    "blue": ("blue", "b", "diffuseblue"),
}
_ROLE_OF = {alias: role for role, aliases in _ALIASES.items() for alias in aliases}
_NORMAL_NAMES = ("nx", "ny", "nz")
_COLOUR_NAMES = ("red", "green", "blue")
# characters a written property name cannot hold: PLY headers are ASCII and split on
# whitespace, text headers split on commas and semicolons
_BAD_NAME = re.compile(r"[^\x21-\x7e]|[,;#\"']")


@dataclass(repr=False, eq=False)
class PointCloud:
    """A point cloud read from a file, with every per-point property it carried.

    Attributes
    ----------
    points : ndarray, shape (n, 3), float64
        Coordinates as stored in the file (LAS: scaled and offset).
    normals : ndarray, shape (n, 3), float64, or None
        Normals from the file (not normalised), if it has all three components.
    colours : ndarray, shape (n, 3), uint8, or None
        RGB colours, scaled to 8 bits (see the notes of :mod:`heatcurv.io`).
    fields : dict of str to ndarray, shape (n,)
        Every other per-point property by its name in the file, with its
        stored dtype (text files: float64). :func:`~heatcurv.io.write_points` writes them
        back when the cloud is passed as ``source``.
    path : pathlib.Path or None
        The file read.
    format : str or None
        The format read: ``"ply"``, ``"las"``, ``"laz"``, ``"xyz"``, ``"txt"``,
        ``"csv"``, ``"pts"``, ``"obj"``, ``"off"``, ``"npy"`` or ``"npz"``.
    meta : dict
        Format details needed to write the cloud back faithfully:
        ``"points_dtype"`` and ``"normals_dtype"`` (the stored types of the
        coordinates and normals, e.g. float32 in many PLY files);
        ``"colour_values"`` (the colours as stored, shape ``(n, 3)``, when
        they are not 8-bit: 16-bit or float colours); ``"faces"`` (the number
        of faces of a PLY, OBJ or OFF mesh). PLY: ``"ply_elements"`` (every
        element other than ``vertex``, e.g. the faces, as
        :class:`plyfile.PlyElement`), ``"ply_comments"`` and
        ``"ply_obj_info"``. LAS/LAZ: ``"las_header"`` (the
        :class:`laspy.LasHeader`: point format, scales, offsets, extra
        dimensions, CRS records) and ``"las_rgb16"`` (the 16-bit colours,
        shape ``(n, 3)``, when the file has RGB).
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    colours: np.ndarray | None = None
    fields: dict = field(default_factory=dict)
    path: Path | None = None
    format: str | None = None
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def __repr__(self) -> str:
        return (
            f"PointCloud(n={len(self)}, format={self.format!r}, "
            f"normals={self.normals is not None}, colours={self.colours is not None}, "
            f"fields={list(self.fields)}, path={str(self.path) if self.path else None!r})"
        )


# ----------------------------------------------------------------------------- helpers


def _one_line(exc: BaseException) -> str:
    """First line of an exception's message, or its type name if it has none."""
    lines = str(exc).strip().splitlines()
    return lines[0].strip() if lines else type(exc).__name__


def _brief(exc: BaseException, limit: int = 100) -> str:
    """:func:`_one_line`, cut to ``limit`` characters (third-party messages may quote whole headers)."""
    line = _one_line(exc)
    return line if len(line) <= limit else line[: limit - 3].rstrip() + "..."


def _quoted(text: str, limit: int = 40) -> str:
    """``repr(text)``, cut to ``limit`` characters of it (``'abc'...``): file content quoted in a one-line message."""
    return repr(text) if len(text) <= limit else repr(text[:limit]) + "..."


def _size_text(nbytes: int) -> str:
    """``3240 bytes``, ``1.5 MB``, ``3.1 GB``: a byte count in plain words."""
    if nbytes < 10_000:
        return f"{nbytes} bytes"
    for unit, scale in (("kB", 1e3), ("MB", 1e6), ("GB", 1e9), ("TB", 1e12)):
        if nbytes < scale * 1000 or unit == "TB":
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes} bytes"  # pragma: no cover


def _read_error(path, problem: str) -> HeatcurvError:
    return HeatcurvError(f"cannot read {path}: {problem}")


def _write_error(path, problem: str) -> HeatcurvError:
    return HeatcurvError(f"cannot write {path}: {problem}")


def _canonical(name: str) -> str:
    """``'Normal_X'`` -> ``'normalx'``: lower case, letters and digits only."""
    return re.sub(r"[^a-z0-9]", "", str(name).lower())


def _native(values: np.ndarray) -> np.ndarray:
    """A contiguous copy in native byte order (PLY big endian, memory maps)."""
    values = np.asarray(values)
    return np.array(values, dtype=values.dtype.newbyteorder("="), copy=True, order="C")


def _is_integral(values: np.ndarray) -> bool:
    """Whether every value is a finite whole number."""
    if values.dtype.kind in "biu":
        return True
    return bool(np.all(np.isfinite(values)) and np.all(values == np.round(values)))


def _colours_to_uint8(rgb: np.ndarray, *, text: bool) -> np.ndarray | None:
    """RGB values of shape (n, 3) as uint8, or None if they do not read as colours.

    ``text=True``: integer values 0-255 are 8-bit, other values in [0, 1] are
    fractions. ``text=False`` (typed files): float values in [0, 1] are
    fractions first. Integers up to 65535 are 16-bit unless all are <= 255.
    """
    rgb = np.asarray(rgb)
    if rgb.dtype == np.uint8:
        return rgb.copy()
    if rgb.dtype.kind not in "iuf" or rgb.size == 0:
        return None
    if rgb.dtype.kind == "f" and not np.all(np.isfinite(rgb)):
        return None
    low, high = rgb.min(), rgb.max()
    if low < 0:
        return None
    integral = _is_integral(rgb)
    fraction = rgb.dtype.kind == "f" and high <= 1.0
    if fraction and (not text or not integral):
        return np.round(rgb * 255.0).astype(np.uint8)
    if integral and high <= 255:
        return rgb.astype(np.uint8)
    if integral and high <= 65535:
        return np.round(rgb / 257.0).astype(np.uint8)
    return None


def _cloud_from_columns(
    columns: dict, path: Path, fmt: str, *, text_colours: bool, meta=None
) -> PointCloud:
    """Assemble a :class:`PointCloud` from named per-point columns.

    Parameters
    ----------
    columns : dict of str to ndarray, shape (n,)
        Every property of the file, in file order.
    path : Path
        The file (for messages).
    fmt : str
        The format label.
    text_colours : bool
        How to read colours (see :func:`_colours_to_uint8`).
    meta : dict, optional
        Stored as :attr:`PointCloud.meta`.
    """
    role_of = {}
    for name in columns:
        role = _ROLE_OF.get(_canonical(name))
        if role is not None and role not in role_of:
            role_of[role] = name
    missing = [axis for axis in "xyz" if axis not in role_of]
    if missing:
        # names as in the file, control characters escaped, at most twelve of 40 characters each
        shown = [str(name) if str(name).isprintable() and len(str(name)) <= 40 else _quoted(str(name))
                 for name in list(columns)[:12]]
        names = ", ".join(shown) + (", ..." if len(columns) > 12 else "") or "none"
        raise _read_error(path, f"no {'/'.join(missing)} coordinate column (columns: {names})")
    meta = dict(meta or {})
    used = [role_of[axis] for axis in "xyz"]
    meta["points_dtype"] = _stored_dtype([columns[name] for name in used])
    points = np.column_stack([np.asarray(columns[name], dtype=np.float64) for name in used])
    n = points.shape[0]
    if n == 0:
        raise _read_error(path, "the file holds no points")

    normals = None
    if all(role in role_of for role in _NORMAL_NAMES):
        names = [role_of[role] for role in _NORMAL_NAMES]
        meta["normals_dtype"] = _stored_dtype([columns[name] for name in names])
        normals = np.column_stack([np.asarray(columns[name], dtype=np.float64) for name in names])
        used += names

    colours = None
    if all(role in role_of for role in _COLOUR_NAMES):
        names = [role_of[role] for role in _COLOUR_NAMES]
        stacked = np.column_stack([np.asarray(columns[name]) for name in names])
        colours = _colours_to_uint8(stacked, text=text_colours)
        if colours is not None:
            used += names
            if stacked.dtype != np.uint8 and not np.array_equal(colours, stacked):
                meta["colour_values"] = stacked  # 16-bit or float colours, written back as stored

    fields = {name: values for name, values in columns.items() if name not in used}
    return PointCloud(
        points=np.ascontiguousarray(points),
        normals=normals,
        colours=colours,
        fields=fields,
        path=path,
        format=fmt,
        meta=meta,
    )


def _stored_dtype(arrays) -> np.dtype:
    """The common dtype of stored coordinate or normal columns: float32 or float64."""
    dtype = np.result_type(*[np.asarray(values).dtype for values in arrays])
    return np.dtype(np.float32) if dtype == np.float32 else np.dtype(np.float64)


def _magic(path: Path, size: int) -> bytes:
    with open(path, "rb") as stream:
        return stream.read(size)


# ----------------------------------------------------------------------------- output records


#: Extensions whose computed float fields are float32 unless ``dtype=`` says otherwise.
_FLOAT32_BY_DEFAULT = (".ply", ".las", ".laz", ".npz")


@dataclass
class _Output:
    """What :func:`~heatcurv.io.write_points` writes, validated: one row per point in every array."""

    points: np.ndarray  # (n, 3) float64
    normals: np.ndarray | None  # (n, 3) float, in the type to write
    colours: np.ndarray | None  # (n, 3) uint8
    columns: dict  # name -> (n,): source properties then the given fields, expanded, types to write
    arrays: dict  # name -> (n,) or (n, 3): the same, (n, 3) fields unexpanded
    source: PointCloud | None
    colours_from_source: bool
    points_dtype: np.dtype = np.dtype(np.float64)  # coordinates in PLY and NPZ: float32 if lossless
    colour_values: np.ndarray | None = None  # the source's colours as stored (16-bit, float), if not 8-bit
    source_names: frozenset = frozenset()  # columns holding a source property unchanged
    uncast: dict = field(default_factory=dict)  # given float64 columns narrowed to float32: the originals


def _float_dtype(path, dtype, ext: str) -> np.dtype:
    """The type of the computed float fields: ``dtype`` (float32 or float64), else the format's default."""
    if dtype is None:
        return np.dtype(np.float32 if ext in _FLOAT32_BY_DEFAULT else np.float64)
    try:
        resolved = np.dtype(dtype)
    except (TypeError, ValueError):
        resolved = None
    if resolved is None or resolved not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise _write_error(path, f"dtype must be float32 or float64, got {dtype!r}")
    return resolved


def _float32_loses(array: np.ndarray) -> bool:
    """Whether float32 would turn a finite value of ``array`` into inf, or a non-zero one into 0 or a subnormal."""
    if array.dtype.itemsize <= 4 or not array.size:
        return False
    magnitude = np.abs(array[np.isfinite(array)])
    info = np.finfo(np.float32)
    return bool(np.any(magnitude > info.max) or np.any((magnitude > 0) & (magnitude < info.tiny)))


def _computed_type(array: np.ndarray, float_dtype: np.dtype, explicit: bool = False, path=None,
                   name: str = "") -> np.ndarray:
    """A given field in the type to write: floats as ``float_dtype``, 64-bit integers narrowed where they fit.

    A float64 field that float32 cannot hold (values beyond 3.4e38 or below 1.2e-38: the
    curvatures and areas of a cloud in extreme units) stays float64 when float32 is only the
    format's default, and is an error when the caller asked for float32 (``explicit``).
    """
    kind = array.dtype.kind
    if kind == "f":
        if float_dtype == np.float32 and _float32_loses(array):
            if explicit:
                raise _write_error(
                    path, f"field {name!r} holds values float32 cannot represent (beyond 3.4e38 or below "
                    "1.2e-38 in magnitude); write it as float64",
                )
            return array
        return array.astype(float_dtype, copy=False)
    if kind in "iu" and array.dtype.itemsize > 4 and array.size:
        low, high = int(array.min()), int(array.max())
        for candidate in (np.int32, np.uint32):
            info = np.iinfo(candidate)
            if info.min <= low and high <= info.max:
                return array.astype(candidate)
    return array


def _check_name(path, name) -> str:
    if not isinstance(name, str) or not name or _BAD_NAME.search(name) or name.startswith("//"):
        raise _write_error(
            path,
            f"field name {name!r} is not usable as a property name "
            "(printable ASCII without spaces, commas, semicolons, quotes or '#')",
        )
    return name


def _as_rows(path, name: str, values, n: int, *, width=None) -> np.ndarray:
    """``values`` as an array of ``n`` rows (of ``width`` columns), numeric or bool."""
    array = np.asarray(values)
    if array.dtype.kind not in "biuf":
        raise _write_error(path, f"{name} must hold numbers or booleans, got dtype {array.dtype}")
    if width is None:
        ok = array.ndim == 1 and array.shape[0] == n or array.shape == (n, 3)
        expected = f"({n},) or ({n}, 3)"
    else:
        ok = array.shape == (n, width)
        expected = f"({n}, {width})"
    if not ok:
        raise _write_error(
            path, f"{name} has shape {array.shape}, expected {expected} (one row per point)"
        )
    return array


def _output(path, points, fields, normals, colours, source, float_dtype=np.float64, explicit=False) -> _Output:
    """Validate and arrange the arrays to write (see :func:`~heatcurv.io.write_points`).

    Given ``fields`` and ``normals`` get the type ``float_dtype`` (floats) or a
    32-bit integer type (64-bit integers that fit); the source's properties and
    normals keep the type they were stored with.
    """
    float_dtype = np.dtype(float_dtype)
    points_array, given_points_dtype = _checked_points(path, points)
    n = points_array.shape[0]
    if source is not None:
        if not isinstance(source, PointCloud):
            raise _write_error(path, f"source must be a PointCloud, got {type(source).__name__}")
        if len(source) != n:
            raise _write_error(path, f"source has {len(source)} points, points has {n}")
    normals = _output_normals(path, normals, source, n, float_dtype)
    colours, colours_from_source, colour_values = _output_colours(path, colours, source, n)
    reserved = (
        {"x", "y", "z"}
        | (set(_NORMAL_NAMES) if normals is not None else set())
        | (set(_COLOUR_NAMES) if colours is not None else set())
    )
    given_columns, given_arrays, uncast = _given_fields(path, fields, n, float_dtype, explicit, reserved)
    columns = _source_columns(path, source, n, reserved, set(given_columns) | set(given_arrays))
    arrays = dict(columns)
    source_names = frozenset(columns)
    columns.update(given_columns)
    arrays.update(given_arrays)

    # coordinates are never narrowed: float32 only where they were float32 and still are exactly
    points_dtype = np.dtype(np.float64)
    stored = source.meta.get("points_dtype") if source is not None else given_points_dtype
    if stored is not None and np.dtype(stored) == np.float32:
        if np.array_equal(points_array.astype(np.float32), points_array, equal_nan=True):
            points_dtype = np.dtype(np.float32)
    return _Output(
        points_array, normals, colours, columns, arrays, source, colours_from_source,
        points_dtype=points_dtype, colour_values=colour_values, source_names=source_names,
        uncast=uncast,
    )


def _checked_points(path, points) -> tuple[np.ndarray, np.dtype]:
    """The coordinates as a contiguous float64 array of shape (n, 3), and the dtype they were given in."""
    points_array = np.asarray(points)
    if points_array.dtype.kind not in "biuf" or points_array.ndim != 2 or points_array.shape[1] != 3:
        raise _write_error(path, f"points must be numbers of shape (n, 3), got shape {points_array.shape}")
    return np.ascontiguousarray(points_array, dtype=np.float64), points_array.dtype


def _output_normals(path, normals, source, n: int, float_dtype: np.dtype) -> np.ndarray | None:
    """The normals to write, shape (n, 3): the given ones in ``float_dtype``, else the source's in their stored type."""
    normals_dtype = float_dtype
    if normals is None and source is not None and source.normals is not None:
        normals = source.normals
        normals_dtype = np.dtype(source.meta.get("normals_dtype", np.float64))
    if normals is None:
        return None
    return _as_rows(path, "normals", normals, n, width=3).astype(normals_dtype)


def _output_colours(path, colours, source, n: int) -> tuple:
    """The colours to write as uint8 rows (or None), whether they are the source's, and the source's own values.

    The source's stored values (``colour_values``: 16-bit colours of a LAS file, say) are written back
    instead of the 8-bit ones when the colours are the source's.
    """
    colours_from_source = False
    if colours is None and source is not None and source.colours is not None:
        colours, colours_from_source = source.colours, True
    elif colours is not None and source is not None and colours is source.colours:
        colours_from_source = True
    colour_values = None
    if colours_from_source:
        colour_values = source.meta.get("colour_values")
        if colour_values is not None and np.shape(colour_values) != (n, 3):
            colour_values = None
    if colours is not None:
        colours = _as_rows(path, "colors", colours, n, width=3)
        if colours.size and (not _is_integral(colours) or colours.min() < 0 or colours.max() > 255):
            raise _write_error(path, "colours must be integers 0-255")
        colours = colours.astype(np.uint8)
    return colours, colours_from_source, colour_values


def _given_fields(path, fields, n: int, float_dtype: np.dtype, explicit: bool, reserved: set) -> tuple:
    """The caller's fields as written properties (vectors split into ``x``, ``y``, ``z``), checked.

    Returns ``(columns, arrays, uncast)``: the properties by name, the arrays by field name, and the
    original values of the properties whose type the write changes.
    """
    if fields is not None and not isinstance(fields, Mapping):
        raise _write_error(path, f"fields must be a dict of name -> array, got {type(fields).__name__}")
    given_columns, given_arrays, uncast = {}, {}, {}
    for name, values in (fields or {}).items():
        _check_name(path, name)
        original = _as_rows(path, f"field {name!r}", values, n)
        array = _computed_type(original, float_dtype, explicit, path, name)
        given_arrays[name] = array
        expanded = {name: array} if array.ndim == 1 else {name + axis: array[:, k] for k, axis in enumerate("xyz")}
        if array.dtype != original.dtype:
            uncast.update(
                {name: original}
                if original.ndim == 1
                else {name + axis: original[:, k] for k, axis in enumerate("xyz")}
            )
        for column, column_values in expanded.items():
            if column.lower() in reserved:
                raise _write_error(
                    path,
                    f"field {name!r} would write the property {column!r}, "
                    "already taken by the points, normals or colours",
                )
            if column in given_columns:
                raise _write_error(path, f"field {name!r} gives the property {column!r} twice")
            given_columns[column] = column_values
    return given_columns, given_arrays, uncast


def _source_columns(path, source, n: int, reserved: set, given: set) -> dict:
    """The source's one-dimensional properties kept in the output, by cleaned name.

    A property whose name is ``reserved`` (any case: coordinates, normals, colours) or ``given`` is left out.
    """
    columns = {}
    if source is None:
        return columns
    for name, values in source.fields.items():
        clean = _BAD_NAME.sub("_", str(name)).lstrip("/") or "field"
        if clean.lower() in reserved or clean in given or clean in columns:
            continue  # replaced by the given values
        array = _as_rows(path, f"source field {name!r}", values, n)
        if array.ndim != 1:
            continue
        columns[clean] = array
    return columns


def _ordered_columns(output: _Output) -> dict:
    """All output properties by name, in the written order: x y z, normals, colours, fields."""
    columns = {axis: output.points[:, k] for k, axis in enumerate("xyz")}
    if output.normals is not None:
        columns.update({name: output.normals[:, k] for k, name in enumerate(_NORMAL_NAMES)})
    if output.colours is not None:
        colours = output.colours if output.colour_values is None else output.colour_values
        columns.update({name: colours[:, k] for k, name in enumerate(_COLOUR_NAMES)})
    columns.update(output.columns)
    return columns
