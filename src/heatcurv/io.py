"""Point-cloud files in and out: PLY, LAS/LAZ, XYZ/TXT/CSV/PTS, OBJ, OFF, NPY/NPZ.

:func:`read_points` turns a scanner's or a photogrammetry tool's file into a
:class:`PointCloud` (float64 coordinates, optional normals and 8-bit colours,
and every other per-point property in ``fields`` so it can be written back out);
:func:`write_points` writes coordinates plus per-point results as named scalar
properties that CloudCompare and MeshLab show as scalar fields. The binary
formats go through the field's libraries (plyfile, laspy with lazrs, numpy);
every failure is a :class:`~heatcurv.errors.HeatcurvError` whose one-line
message names the file and the problem.

=============================  ========================  =======================
extension                      read                      write
=============================  ========================  =======================
``.ply``                       ascii, binary le/be       binary little endian
``.las`` ``.laz``              laspy (lazrs for LAZ)     laspy, extra dimensions
``.xyz`` ``.txt`` ``.pts``     header and delimiter      space-delimited, ``#``
                               detected                  header (not ``.pts``)
``.csv``                       as above                  comma, header line
``.obj``                       ``v`` lines               --
``.off``                       vertices (C/N/ST OFF)     --
``.npy``                       ``(n, >=3)`` array        --
``.npz``                       ``points`` or ``xyz``     ``points`` + arrays
=============================  ========================  =======================

Conventions
-----------
Property names are matched case-insensitively with ``_``, spaces and other
punctuation ignored: ``x y z``; normals ``nx ny nz`` (also ``normal_x`` ...);
colours ``red green blue`` (also ``r g b``, ``diffuse_red`` ...). Normals and
colours need all three components, otherwise the components stay in
``fields``; so do colours that cannot be read as 8-bit values.

Colours are stored as ``uint8``. Integer 16-bit colours (LAS, PLY ``ushort``)
are scaled by ``1/257`` unless all values are at most 255 (files that store
8-bit values in 16-bit fields, the CloudCompare rule); float colours in
``[0, 1]`` (PLY, OBJ, NPZ, Geomview OFF) are scaled by 255. Text columns are
plain numbers: integer values 0-255 are 8-bit colours, other values in
``[0, 1]`` are fractions.

Text files: the delimiter is ``;`` if the first data line holds one (decimal
commas are then accepted), else ``,``, else runs of spaces and tabs. Lines
starting with ``#`` or ``//`` are comments. The header is an uncommented line
before the data holding a non-number, or else the comment line just before the
data if it names ``x``, ``y`` and ``z`` (``# x y z ...`` as written here,
CloudCompare's ``//X,Y,Z,...``). A first line holding only an integer (the PTS
point count) is skipped; in ``.pts`` files every such line is (one per scan).
Files without a header are read by their column count:

=======  ================================================================
columns  meaning
=======  ================================================================
3        ``x y z``
6        ``x y z red green blue`` if columns 4-6 are integers 0-255 and not
         all rows are unit vectors, else ``x y z nx ny nz``
7        ``x y z intensity red green blue`` (PTS) when columns 5-7 are
         integers 0-255
9        ``x y z`` + normals and colours, in whichever order the integer
         0-255 columns say
10       ``x y z intensity red green blue nx ny nz`` (PTS with normals)
other    ``x y z`` and ``column_4``, ``column_5``, ... (1-based column number)
=======  ================================================================

A ``.pts`` column 4 of a 4-column file is ``intensity``. Text fields are read
as float64.

Writing is atomic: the file is written to a temporary file in the target
directory and moved over the target with :func:`os.replace`; on a failure the
temporary file is removed, so there is never a partial output, and an existing
file of the same name stays as it was.
"""

from __future__ import annotations

import io as _stdio
import os
import re
import tempfile
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import HeatcurvError

__all__ = ["PointCloud", "SUPPORTED_READ", "SUPPORTED_WRITE", "read_points", "write_points"]

#: Extensions :func:`read_points` understands (compared case-insensitively).
SUPPORTED_READ = (
    ".ply",
    ".las",
    ".laz",
    ".xyz",
    ".txt",
    ".csv",
    ".pts",
    ".obj",
    ".off",
    ".npy",
    ".npz",
)
#: Extensions :func:`write_points` can write (compared case-insensitively).
SUPPORTED_WRITE = (".ply", ".las", ".laz", ".csv", ".xyz", ".txt", ".npz")

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
_COLOR_NAMES = ("red", "green", "blue")

# characters a written property name cannot hold: PLY headers are ASCII and split on
# whitespace, text headers split on commas and semicolons
_BAD_NAME = re.compile(r"[^\x21-\x7e]|[,;#\"']")
# LAS point formats without RGB -> the same format with RGB
_LAS_WITH_RGB = {0: 2, 1: 3, 2: 2, 3: 3, 4: 5, 5: 5, 6: 7, 7: 7, 8: 8, 9: 10, 10: 10}
# plyfile's scalar types
_PLY_TYPES = {"i1", "u1", "i2", "u2", "i4", "u4", "f4", "f8"}
# rows formatted per call when writing text
_TEXT_BLOCK = 65536


@dataclass(repr=False, eq=False)
class PointCloud:
    """A point cloud read from a file, with every per-point property it carried.

    Attributes
    ----------
    points : ndarray, shape (n, 3), float64
        Coordinates as stored in the file (LAS: scaled and offset).
    normals : ndarray, shape (n, 3), float64, or None
        Normals from the file (not normalised), if it has all three components.
    colors : ndarray, shape (n, 3), uint8, or None
        RGB colours, scaled to 8 bits (see the module notes).
    fields : dict of str to ndarray, shape (n,)
        Every other per-point property by its name in the file, with its
        stored dtype (text files: float64). :func:`write_points` writes them
        back when the cloud is passed as ``source``.
    path : pathlib.Path or None
        The file read.
    format : str or None
        The format read: ``"ply"``, ``"las"``, ``"laz"``, ``"xyz"``, ``"txt"``,
        ``"csv"``, ``"pts"``, ``"obj"``, ``"off"``, ``"npy"`` or ``"npz"``.
    meta : dict
        Format details needed to write the cloud back faithfully: for LAS/LAZ
        ``"las_header"`` (the :class:`laspy.LasHeader`: point format, scales,
        offsets, CRS records) and ``"las_rgb16"`` (the 16-bit colours, shape
        ``(n, 3)``, when the file has RGB).
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    fields: dict = field(default_factory=dict)
    path: Path | None = None
    format: str | None = None
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def __repr__(self) -> str:
        return (
            f"PointCloud(n={len(self)}, format={self.format!r}, "
            f"normals={self.normals is not None}, colors={self.colors is not None}, "
            f"fields={list(self.fields)}, path={str(self.path) if self.path else None!r})"
        )


# ----------------------------------------------------------------------------- helpers


def _one_line(exc: BaseException) -> str:
    """First line of an exception's message, or its type name if it has none."""
    lines = str(exc).strip().splitlines()
    return lines[0].strip() if lines else type(exc).__name__


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


def _colors_to_uint8(rgb: np.ndarray, *, text: bool) -> np.ndarray | None:
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


def _looks_like_rgb(block: np.ndarray) -> bool:
    """Columns (n, 3) of integers 0-255 that are not all unit vectors (normals)."""
    if block.size == 0 or not _is_integral(block) or block.min() < 0 or block.max() > 255:
        return False
    unit = np.abs(np.linalg.norm(block, axis=1) - 1.0) < 1e-3
    return not bool(np.all(unit))


def _cloud_from_columns(
    columns: dict, path: Path, fmt: str, *, text_colors: bool, meta=None
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
    text_colors : bool
        How to read colours (see :func:`_colors_to_uint8`).
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
        names = ", ".join(columns) or "none"
        raise _read_error(path, f"no {'/'.join(missing)} coordinate column (columns: {names})")
    used = []
    points = np.column_stack(
        [np.asarray(columns[role_of[axis]], dtype=np.float64) for axis in "xyz"]
    )
    used += [role_of[axis] for axis in "xyz"]
    n = points.shape[0]
    if n == 0:
        raise _read_error(path, "the file holds no points")

    normals = None
    if all(role in role_of for role in _NORMAL_NAMES):
        names = [role_of[role] for role in _NORMAL_NAMES]
        normals = np.column_stack([np.asarray(columns[name], dtype=np.float64) for name in names])
        used += names

    colors = None
    if all(role in role_of for role in _COLOR_NAMES):
        names = [role_of[role] for role in _COLOR_NAMES]
        stacked = np.column_stack([np.asarray(columns[name]) for name in names])
        colors = _colors_to_uint8(stacked, text=text_colors)
        if colors is not None:
            used += names

    fields = {name: values for name, values in columns.items() if name not in used}
    return PointCloud(
        points=np.ascontiguousarray(points),
        normals=normals,
        colors=colors,
        fields=fields,
        path=path,
        format=fmt,
        meta=dict(meta or {}),
    )


# ----------------------------------------------------------------------------- reading


def read_points(path) -> PointCloud:
    """Read a point cloud file, choosing the reader by its extension.

    Parameters
    ----------
    path : str or os.PathLike
        A file with one of the extensions in :data:`SUPPORTED_READ`
        (case-insensitive).

    Returns
    -------
    PointCloud
        ``points`` of shape (n, 3) float64, optional ``normals`` (n, 3) and
        ``colors`` (n, 3) uint8, every other per-point property in ``fields``.
        Rows holding NaN are kept as they are (``heatcurv.estimate`` reports
        them). PLY: only the ``vertex`` element is read, list properties are
        skipped. OBJ: ``v`` lines only. OFF: vertices only.

    Raises
    ------
    HeatcurvError
        If the file is missing or unreadable, its extension is not supported,
        it holds no points, it is truncated or not of the format its extension
        says, a text row has the wrong number of values or a non-number (the
        message gives the line), or it has no x, y, z coordinates.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if not path.exists():
        raise _read_error(path, "no such file")
    if path.is_dir():
        raise _read_error(path, "it is a directory, not a file")
    reader = _READERS.get(ext)
    if reader is None:
        raise _read_error(
            path, f"unknown extension {ext or '(none)'!r}; supported: {' '.join(SUPPORTED_READ)}"
        )
    try:
        if path.stat().st_size == 0:
            raise _read_error(path, "the file is empty")
        return reader(path, ext[1:])
    except HeatcurvError:
        raise
    except OSError as exc:
        raise _read_error(path, exc.strerror or _one_line(exc)) from exc


def _read_ply(path: Path, fmt: str) -> PointCloud:
    import plyfile

    if _magic(path, 3) != b"ply":
        raise _read_error(path, "not a valid PLY file (it does not start with 'ply')")
    try:
        # First a memory-mapped read with triangle faces of known length (fast for big
        # meshes); on any failure (other face sizes, no mmap, ...) a plain read, whose
        # error is the one reported.
        try:
            with open(path, "rb") as stream:
                ply = plyfile.PlyData.read(
                    stream,
                    mmap="c",
                    known_list_len={"face": {"vertex_indices": 3, "vertex_index": 3}},
                )
        except Exception:
            with open(path, "rb") as stream:
                ply = plyfile.PlyData.read(stream, mmap=False)
    except OSError:
        raise
    except Exception as exc:  # plyfile raises parse, value, unicode and memory errors
        raise _read_error(path, f"not a valid PLY file ({_one_line(exc)})") from None

    names = [element.name for element in ply.elements]
    if "vertex" not in names:
        raise _read_error(
            path, f"no 'vertex' element in the PLY file (elements: {', '.join(names) or 'none'})"
        )
    vertex = ply["vertex"]
    columns = {
        prop.name: _native(vertex.data[prop.name])
        for prop in vertex.properties
        if not isinstance(prop, plyfile.PlyListProperty)
    }
    return _cloud_from_columns(columns, path, fmt, text_colors=False)


def _read_las(path: Path, fmt: str) -> PointCloud:
    import laspy

    try:
        las = laspy.read(path)
        points = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)]).astype(
            np.float64
        )
        dimension_names = list(las.point_format.dimension_names)
        extra_names = set(las.point_format.extra_dimension_names)
        columns = {}
        for name in dimension_names:
            if name in ("X", "Y", "Z", "red", "green", "blue"):
                continue
            values = np.array(las[name])
            if values.ndim == 2:  # array extra bytes ("3f8"): one field per element
                for k in range(values.shape[1]):
                    columns[f"{name}_{k}"] = values[:, k].copy()
            else:
                columns[name] = values
        rgb16 = None
        if "red" in dimension_names:
            rgb16 = np.column_stack(
                [np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)]
            ).astype(np.uint16)
        header = las.header
    except OSError:
        raise
    except Exception as exc:  # laspy / lazrs errors on garbage or truncated data
        raise _read_error(path, f"not a valid LAS/LAZ file ({_one_line(exc)})") from None

    if points.shape[0] < header.point_count:
        raise _read_error(
            path,
            f"truncated: the header announces {header.point_count} points, "
            f"the file holds {points.shape[0]}",
        )
    if points.shape[0] == 0:
        raise _read_error(path, "the file holds no points")
    normals = None
    role_of = {}
    for name in columns:
        role = _ROLE_OF.get(_canonical(name))
        if name in extra_names and role in _NORMAL_NAMES and role not in role_of:
            role_of[role] = name
    if all(role in role_of for role in _NORMAL_NAMES):
        normals = np.column_stack(
            [columns.pop(role_of[role]).astype(np.float64) for role in _NORMAL_NAMES]
        )
    colors = None
    meta = {"las_header": header}
    if rgb16 is not None:
        colors = (
            rgb16.astype(np.uint8)
            if rgb16.max(initial=0) <= 255
            else np.round(rgb16 / 257.0).astype(np.uint8)
        )
        meta["las_rgb16"] = rgb16
    return PointCloud(
        points=np.ascontiguousarray(points),
        normals=normals,
        colors=colors,
        fields=columns,
        path=path,
        format=fmt,
        meta=meta,
    )


def _decode_text(path: Path) -> str:
    """The file as text with ``\\n`` line ends (UTF-8, else Latin-1)."""
    raw = path.read_bytes()
    if b"\x00" in raw[:65536]:
        raise _read_error(path, "binary data, not a text file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return text.replace("\r\n", "\n").replace("\r", "\n")


def _strip_comment(line: str) -> str:
    """The line without a ``#`` or ``//`` comment, stripped."""
    for marker in ("#", "//"):
        cut = line.find(marker)
        if cut >= 0:
            line = line[:cut]
    return line.strip()


def _split(line: str, delimiter: str | None) -> list:
    """Tokens of a line, stripped of spaces and quotes (``delimiter`` None: whitespace)."""
    return [token.strip().strip("\"'") for token in line.split(delimiter)]


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _guess_delimiter(line: str) -> str | None:
    """``;`` or ``,`` if the line holds one, else None (runs of spaces and tabs)."""
    if ";" in line:
        return ";"
    if "," in line:
        return ","
    return None


def _iter_lines(text: str):
    """Yield ``(line_number, line)`` from the start of ``text`` (1-based, lazily)."""
    start, number = 0, 0
    while start <= len(text):
        end = text.find("\n", start)
        if end < 0:
            end = len(text)
        number += 1
        yield number, text[start:end]
        start = end + 1


def _first_bad_line(text: str, skip: int, ncols: int, delimiter, max_rows=None):
    """Find the first data line after ``skip`` lines with the wrong count or a non-number.

    Only called after numpy's fast parser failed. Returns ``(line_number,
    problem)`` or None.
    """
    rows = 0
    for number, line in _iter_lines(text):
        if number <= skip:
            continue
        content = _strip_comment(line)
        if not content:
            continue
        tokens = _split(content, delimiter)
        if len(tokens) != ncols:
            return number, f"expected {ncols} values, found {len(tokens)}"
        for column, token in enumerate(tokens, start=1):
            if not _is_number(token):
                shown = repr(token) if token else "an empty value"
                return number, f"column {column} holds {shown}, not a number"
        rows += 1
        if max_rows is not None and rows >= max_rows:
            return None
    return None


def _load_table(
    path: Path, text: str, skip: int, ncols: int, delimiter, max_rows=None
) -> np.ndarray:
    """Parse the numbers after ``skip`` lines with numpy; bad lines raise with their number.

    Returns
    -------
    ndarray, shape (m, ncols), float64
    """
    try:
        table = np.loadtxt(
            _stdio.StringIO(text),
            dtype=np.float64,
            delimiter=delimiter,
            comments=("#", "//"),
            skiprows=skip,
            max_rows=max_rows,
            ndmin=2,
        )
    except ValueError as exc:
        bad = _first_bad_line(text, skip, ncols, delimiter, max_rows)
        if bad is None:
            raise _read_error(path, f"cannot parse the numbers ({_one_line(exc)})") from None
        number, problem = bad
        raise _read_error(path, f"line {number}: {problem}") from None
    if table.size and table.shape[1] != ncols:  # numpy agrees with the first line's count
        bad = _first_bad_line(text, skip, ncols, delimiter, max_rows)
        raise _read_error(
            path, f"line {bad[0]}: {bad[1]}" if bad else f"expected {ncols} values per line"
        )
    return table


def _unique_names(names: list) -> list:
    """Header names made unique: a repeated ``name`` becomes ``name_2``, ``name_3``..."""
    seen, out = {}, []
    for index, name in enumerate(names, start=1):
        name = name or f"column_{index}"
        count = seen.get(name, 0) + 1
        seen[name] = count
        out.append(name if count == 1 else f"{name}_{count}")
    return out


def _positional_names(table: np.ndarray, ext: str) -> list:
    """Column names of a header-less text table (see the module notes)."""
    ncols = table.shape[1]
    extra = [f"column_{k}" for k in range(4, ncols + 1)]
    names = ["x", "y", "z"] + extra
    if ncols == 4 and ext == ".pts":
        names = ["x", "y", "z", "intensity"]
    elif ncols == 6:
        names = ["x", "y", "z"] + (
            list(_COLOR_NAMES) if _looks_like_rgb(table[:, 3:6]) else list(_NORMAL_NAMES)
        )
    elif ncols == 7 and _looks_like_rgb(table[:, 4:7]):
        names = ["x", "y", "z", "intensity", *_COLOR_NAMES]
    elif ncols == 9:
        if _looks_like_rgb(table[:, 3:6]) and not _looks_like_rgb(table[:, 6:9]):
            names = ["x", "y", "z", *_COLOR_NAMES, *_NORMAL_NAMES]
        elif _looks_like_rgb(table[:, 6:9]):
            names = ["x", "y", "z", *_NORMAL_NAMES, *_COLOR_NAMES]
    elif ncols == 10 and _looks_like_rgb(table[:, 4:7]):
        names = ["x", "y", "z", "intensity", *_COLOR_NAMES, *_NORMAL_NAMES]
    return names


def _read_text(path: Path, fmt: str) -> PointCloud:
    ext = "." + fmt
    text = _decode_text(path)
    if ext == ".pts":
        # Leica PTS: each scan starts with a line holding its point count.
        text = re.sub(r"(?m)^[ \t]*\d+[ \t]*$", "", text)

    header_line = header_content = None  # an uncommented header line
    last_comment = None  # (line number, text) of the latest comment line
    data_line = data_content = None
    for number, line in _iter_lines(text):
        stripped = line.strip()
        if stripped.startswith(("#", "//")):
            last_comment = (number, stripped.lstrip("#/").strip())
            continue
        content = _strip_comment(line)
        if not content:
            continue
        tokens = _split(content, _guess_delimiter(content))
        leading = header_line is None and last_comment is None
        if leading and len(tokens) == 1 and re.fullmatch(r"\d+", tokens[0]):
            last_comment = (number, "")  # a leading point count (PTS style); no header after it
            continue
        decimal_comma = ";" in content
        if header_line is None and not all(
            _is_number(t.replace(",", ".") if decimal_comma else t) for t in tokens
        ):
            header_line, header_content = number, content
            continue
        data_line, data_content = number, content
        break
    if data_line is None:
        raise _read_error(path, "the file holds no points")

    delimiter = _guess_delimiter(data_content)
    if delimiter == ";" and "," in data_content and "." not in data_content:
        text = text.replace(",", ".")  # decimal commas (semicolon-separated exports)
        data_content = data_content.replace(",", ".")
    ncols = len(_split(data_content, delimiter))

    names = None
    if header_content is not None:
        names = _split(header_content, delimiter)
        if len(names) != ncols:
            names = _split(header_content, _guess_delimiter(header_content))
        if len(names) != ncols:
            raise _read_error(
                path,
                f"line {header_line}: the header names {len(names)} columns "
                f"but line {data_line} has {ncols} values",
            )
    elif last_comment is not None and last_comment[1]:
        candidate = _split(last_comment[1], delimiter)
        if len(candidate) != ncols:
            candidate = _split(last_comment[1], _guess_delimiter(last_comment[1]))
        roles = {_ROLE_OF.get(_canonical(name)) for name in candidate}
        if len(candidate) == ncols and {"x", "y", "z"} <= roles:
            names = candidate

    if ncols < 3:
        raise _read_error(
            path, f"line {data_line}: expected at least 3 values (x y z), found {ncols}"
        )
    table = _load_table(path, text, data_line - 1, ncols, delimiter)
    if table.shape[0] == 0:
        raise _read_error(path, "the file holds no points")
    names = _unique_names(names) if names is not None else _positional_names(table, ext)
    columns = {name: np.ascontiguousarray(table[:, k]) for k, name in enumerate(names)}
    return _cloud_from_columns(columns, path, fmt, text_colors=True)


def _read_obj(path: Path, fmt: str) -> PointCloud:
    text = _decode_text(path)
    vertex_lines = re.findall(r"(?m)^[ \t]*v[ \t]+([^\n]*)$", text)
    if not vertex_lines:
        raise _read_error(path, "no vertices ('v' lines) in the OBJ file")
    ncols = len(_strip_comment(vertex_lines[0]).split())
    if ncols not in (3, 4, 6):
        raise _read_error(
            path,
            f"line {_obj_line_number(text, 0)}: a 'v' line has {ncols} values; "
            "expected 3 (x y z), 4 (x y z w) or 6 (x y z r g b)",
        )
    body = "\n".join(vertex_lines)
    try:
        table = np.loadtxt(_stdio.StringIO(body), dtype=np.float64, comments="#", ndmin=2)
        if table.shape[1] != ncols:
            raise ValueError("column count")
    except ValueError:
        bad = _first_bad_line(body, 0, ncols, None)
        if bad is None:
            raise _read_error(path, "cannot parse the 'v' lines") from None
        raise _read_error(path, f"line {_obj_line_number(text, bad[0] - 1)}: {bad[1]}") from None
    names = {3: ["x", "y", "z"], 4: ["x", "y", "z", "w"], 6: ["x", "y", "z", *_COLOR_NAMES]}[ncols]
    columns = {name: np.ascontiguousarray(table[:, k]) for k, name in enumerate(names)}
    return _cloud_from_columns(columns, path, fmt, text_colors=False)


def _obj_line_number(text: str, vertex_index: int) -> int:
    """Line number in the file of the ``vertex_index``-th ``v`` line (error path only)."""
    for index, match in enumerate(re.finditer(r"(?m)^[ \t]*v[ \t]+", text)):
        if index == vertex_index:
            return text.count("\n", 0, match.start()) + 1
    return 0


def _read_off(path: Path, fmt: str) -> PointCloud:
    text = _decode_text(path)
    lines = _iter_lines(text)
    keyword = None
    tokens = []
    for number, line in lines:
        content = line.split("#", 1)[0].strip()
        if content:
            keyword, *tokens = content.split()
            break
    match = re.fullmatch(r"(ST)?(C)?(N)?(4)?(n)?OFF", keyword or "")
    if match is None:
        raise _read_error(
            path, f"not an OFF file (first word {keyword!r}, expected OFF, COFF, NOFF, ...)"
        )
    if "BINARY" in tokens:
        raise _read_error(path, "binary OFF is not supported; save it as ASCII OFF or PLY")
    if match.group(4) or match.group(5):
        raise _read_error(path, f"{keyword} (4-D or n-D vertices) is not supported")
    counts_line = number
    while len(tokens) < 1:
        try:
            counts_line, line = next(lines)
        except StopIteration:
            raise _read_error(path, "the OFF header has no vertex count") from None
        tokens = line.split("#", 1)[0].split()
    try:
        n_vertices = int(tokens[0])
    except ValueError:
        raise _read_error(
            path, f"line {counts_line}: {tokens[0]!r} is not a vertex count"
        ) from None
    if n_vertices <= 0:
        raise _read_error(path, "the file holds no points")

    first = None
    for number, line in lines:
        content = line.split("#", 1)[0].strip()
        if content:
            first = (number, content)
            break
    if first is None:
        raise _read_error(
            path, f"truncated: the header announces {n_vertices} vertices, the file has none"
        )
    ncols = len(first[1].split())
    table = _load_table(path, text, first[0] - 1, ncols, None, max_rows=n_vertices)
    if table.shape[0] < n_vertices:
        raise _read_error(
            path,
            f"truncated: the header announces {n_vertices} vertices, the file has {table.shape[0]}",
        )

    has_texture, has_color, has_normal = (bool(match.group(k)) for k in (1, 2, 3))
    n_color = ncols - 3 - 3 * has_normal - 2 * has_texture
    if (has_color and n_color not in (3, 4)) or (not has_color and n_color != 0):
        raise _read_error(path, f"line {first[0]}: {ncols} values do not match a {keyword} vertex")
    names = ["x", "y", "z"] + (list(_NORMAL_NAMES) if has_normal else [])
    columns = {name: np.ascontiguousarray(table[:, k]) for k, name in enumerate(names)}
    cloud = _cloud_from_columns(columns, path, fmt, text_colors=False)
    if has_color:
        start = len(names)
        rgba = table[:, start : start + n_color]
        # Geomview colours are floats 0-1, MeshLab writes integers 0-255 (alpha included)
        as_bytes = _is_integral(rgba) and rgba.max(initial=0) > 1
        cloud.colors = _colors_to_uint8(rgba[:, :3], text=as_bytes)
        if cloud.colors is None:
            raise _read_error(path, "vertex colours are neither 0-255 integers nor 0-1 fractions")
        if n_color == 4:
            cloud.fields["alpha"] = np.ascontiguousarray(rgba[:, 3])
    if has_texture:
        start = ncols - 2
        cloud.fields["s"] = np.ascontiguousarray(table[:, start])
        cloud.fields["t"] = np.ascontiguousarray(table[:, start + 1])
    return cloud


def _magic(path: Path, size: int) -> bytes:
    with open(path, "rb") as stream:
        return stream.read(size)


def _read_npy(path: Path, fmt: str) -> PointCloud:
    if _magic(path, 6) != b"\x93NUMPY":
        raise _read_error(path, "not a valid NPY file (no NumPy array header)")
    try:
        array = np.load(path, allow_pickle=False)
    except Exception as exc:
        raise _read_error(path, f"not a valid NPY file ({_one_line(exc)})") from None
    if not isinstance(array, np.ndarray):
        raise _read_error(path, "not a single NPY array")
    if array.dtype.names:
        if array.ndim != 1:
            raise _read_error(path, f"a structured array must have shape (n,), got {array.shape}")
        columns = {
            name: _native(array[name]) for name in array.dtype.names if array[name].ndim == 1
        }
        return _cloud_from_columns(columns, path, fmt, text_colors=False)
    if array.dtype.kind not in "biuf":
        raise _read_error(path, f"the array holds {array.dtype} values, not numbers")
    if array.ndim != 2 or array.shape[1] < 3:
        raise _read_error(
            path, f"the array has shape {array.shape}; expected (n, 3) or (n, k >= 3)"
        )
    if array.shape[0] == 0:
        raise _read_error(path, "the file holds no points")
    ncols = array.shape[1]
    names = ["x", "y", "z"] + (
        list(_NORMAL_NAMES) if ncols == 6 else [f"column_{k}" for k in range(4, ncols + 1)]
    )
    columns = {name: _native(array[:, k]) for k, name in enumerate(names)}
    return _cloud_from_columns(columns, path, fmt, text_colors=False)


def _read_npz(path: Path, fmt: str) -> PointCloud:
    if _magic(path, 4) not in (b"PK\x03\x04", b"PK\x05\x06"):
        raise _read_error(path, "not a valid NPZ file (not a zip archive of NumPy arrays)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            if not hasattr(archive, "files"):
                raise ValueError("not an NPZ archive")
            arrays = {key: archive[key] for key in archive.files}
    except Exception as exc:
        raise _read_error(path, f"not a valid NPZ file ({_one_line(exc)})") from None
    key = "points" if "points" in arrays else "xyz" if "xyz" in arrays else None
    if key is None:
        raise _read_error(
            path, f"no 'points' or 'xyz' array (arrays: {', '.join(arrays) or 'none'})"
        )
    points = arrays.pop(key)
    if points.dtype.kind not in "biuf" or points.ndim != 2 or points.shape[1] != 3:
        raise _read_error(
            path,
            f"'{key}' has shape {points.shape} and dtype {points.dtype}; expected (n, 3) numbers",
        )
    n = points.shape[0]
    if n == 0:
        raise _read_error(path, "the file holds no points")
    normals = arrays.pop("normals", None)
    if normals is not None:
        if normals.dtype.kind not in "biuf" or normals.shape != (n, 3):
            raise _read_error(
                path, f"'normals' has shape {normals.shape}; expected ({n}, 3) like the points"
            )
        normals = _native(normals).astype(np.float64)
    colors = arrays.pop("colors", None)
    if colors is not None:
        converted = _colors_to_uint8(colors, text=False) if colors.shape == (n, 3) else None
        if converted is None:
            raise _read_error(
                path,
                f"'colors' (shape {colors.shape}, dtype {colors.dtype}) "
                f"are not ({n}, 3) RGB values",
            )
        colors = converted
    fields = {}
    for name, values in arrays.items():
        if values.dtype.kind not in "biuf" or values.ndim not in (1, 2) or values.shape[0] != n:
            continue  # not a per-point array (metadata): ignored
        if values.ndim == 1:
            fields[name] = _native(values)
        else:
            suffixes = "xyz" if values.shape[1] == 3 else [f"_{k}" for k in range(values.shape[1])]
            for k, suffix in enumerate(suffixes):
                fields[f"{name}{suffix}"] = _native(values[:, k])
    return PointCloud(
        points=np.ascontiguousarray(points, dtype=np.float64),
        normals=normals,
        colors=colors,
        fields=fields,
        path=path,
        format=fmt,
    )


_READERS = {
    ".ply": _read_ply,
    ".las": _read_las,
    ".laz": _read_las,
    ".xyz": _read_text,
    ".txt": _read_text,
    ".csv": _read_text,
    ".pts": _read_text,
    ".obj": _read_obj,
    ".off": _read_off,
    ".npy": _read_npy,
    ".npz": _read_npz,
}


# ----------------------------------------------------------------------------- writing


@dataclass
class _Output:
    """What :func:`write_points` writes, validated: one row per point in every array."""

    points: np.ndarray  # (n, 3) float64
    normals: np.ndarray | None  # (n, 3) float
    colors: np.ndarray | None  # (n, 3) uint8
    columns: dict  # name -> (n,): source properties then the given fields, expanded
    arrays: dict  # name -> (n,) or (n, 3): the same, (n, 3) fields unexpanded (NPZ)
    source: PointCloud | None
    colors_from_source: bool


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


def _output(path, points, fields, normals, colors, source) -> _Output:
    """Validate and arrange the arrays to write (see :func:`write_points`)."""
    points_array = np.asarray(points)
    if (
        points_array.dtype.kind not in "biuf"
        or points_array.ndim != 2
        or points_array.shape[1] != 3
    ):
        raise _write_error(
            path, f"points must be numbers of shape (n, 3), got shape {points_array.shape}"
        )
    points_array = np.ascontiguousarray(points_array, dtype=np.float64)
    n = points_array.shape[0]

    if source is not None:
        if not isinstance(source, PointCloud):
            raise _write_error(path, f"source must be a PointCloud, got {type(source).__name__}")
        if len(source) != n:
            raise _write_error(path, f"source has {len(source)} points, points has {n}")
    colors_from_source = False
    if normals is None and source is not None:
        normals = source.normals
    if colors is None and source is not None and source.colors is not None:
        colors, colors_from_source = source.colors, True
    elif colors is not None and source is not None and colors is source.colors:
        colors_from_source = True
    if normals is not None:
        normals = _as_rows(path, "normals", normals, n, width=3)
        normals = normals.astype(normals.dtype if normals.dtype.kind == "f" else np.float64)
    if colors is not None:
        colors = _as_rows(path, "colors", colors, n, width=3)
        if colors.size and (not _is_integral(colors) or colors.min() < 0 or colors.max() > 255):
            raise _write_error(path, "colors must be integers 0-255")
        colors = colors.astype(np.uint8)

    reserved = (
        {"x", "y", "z"}
        | (set(_NORMAL_NAMES) if normals is not None else set())
        | (set(_COLOR_NAMES) if colors is not None else set())
    )
    if fields is not None and not isinstance(fields, Mapping):
        raise _write_error(
            path, f"fields must be a dict of name -> array, got {type(fields).__name__}"
        )
    given_columns, given_arrays = {}, {}
    for name, values in (fields or {}).items():
        _check_name(path, name)
        array = _as_rows(path, f"field {name!r}", values, n)
        given_arrays[name] = array
        expanded = (
            {name: array}
            if array.ndim == 1
            else {name + axis: array[:, k] for k, axis in enumerate("xyz")}
        )
        for column, column_values in expanded.items():
            if column.lower() in reserved:
                raise _write_error(
                    path,
                    f"field {name!r} would write the property {column!r}, "
                    "already taken by the points, normals or colors",
                )
            if column in given_columns:
                raise _write_error(path, f"field {name!r} gives the property {column!r} twice")
            given_columns[column] = column_values

    columns, arrays = {}, {}
    if source is not None:
        for name, values in source.fields.items():
            clean = _BAD_NAME.sub("_", str(name)).lstrip("/") or "field"
            if (
                clean.lower() in reserved
                or clean in given_columns
                or clean in given_arrays
                or clean in columns
            ):
                continue  # replaced by the given values
            array = _as_rows(path, f"source field {name!r}", values, n)
            if array.ndim != 1:
                continue
            columns[clean] = arrays[clean] = array
    columns.update(given_columns)
    arrays.update(given_arrays)
    return _Output(points_array, normals, colors, columns, arrays, source, colors_from_source)


def write_points(path, points, fields=None, *, normals=None, colors=None, source=None) -> None:
    """Write points and per-point fields to a file, atomically, choosing the format by extension.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its extension (case-insensitive) picks the format, one of
        :data:`SUPPORTED_WRITE`. An existing file is replaced only once the
        new one is complete.
    points : array_like, shape (n, 3)
        Coordinates (NaN allowed except in LAS/LAZ).
    fields : dict of str to array_like, shape (n,) or (n, 3), optional
        Per-point values written as scalar properties with exactly these
        names, after those of ``source``; an (n, 3) field ``d1`` becomes
        ``d1x d1y d1z``. Booleans are written as 0/1 (``uint8``). A given
        field replaces a source property of the same name.
    normals : array_like, shape (n, 3), optional
        Written as ``nx ny nz``; default: ``source.normals``.
    colors : array_like, shape (n, 3), integers 0-255, optional
        Written as ``red green blue`` (uint8; LAS 16-bit, ``value * 257``);
        default: ``source.colors``.
    source : PointCloud, optional
        The cloud the points came from: its ``fields`` are written back (and
        its normals and colours unless given). For LAS/LAZ output from a LAS
        source the header's point format, version, scales, offsets and
        records (CRS) are kept and 16-bit colours written unchanged.

    Notes
    -----
    Property order: ``x y z``, ``nx ny nz``, ``red green blue``, the source's
    fields, the given fields.

    ``.ply``: binary little endian, ``x y z`` as double; other properties keep
    their dtype (int64 values become int32/uint32 where they fit, else
    double; float16 becomes float).
    ``.las``/``.laz``: LAS 1.4 point format 6 (7 with colours) unless the
    source is LAS; fields named like a standard dimension of the point format
    (``intensity``, ``classification``, ...) fill it when their values fit
    exactly, the others become extra-bytes dimensions (names of at most 32
    characters). Scales are a power of ten at most 1e-6 of the largest
    bounding-box side.
    ``.csv``: comma-separated with a header line; ``.xyz``/``.txt``:
    space-separated with a ``# x y z ...`` header line. Floats are written
    with 17 significant digits (``%.17g``), so they read back exactly.
    ``.npz``: arrays ``points``, ``normals``, ``colors`` and each field
    ((n, 3) fields as one array).

    Raises
    ------
    HeatcurvError
        On an unsupported extension, arrays that do not have one row per
        point, unusable or repeated field names, values the format cannot
        hold (NaN coordinates in LAS, fields that do not fit a standard LAS
        dimension), or an OS error (missing directory, permissions).
    """
    path = Path(path)
    ext = path.suffix.lower()
    writer = _WRITERS.get(ext)
    if writer is None:
        raise _write_error(
            path, f"unknown extension {ext or '(none)'!r}; supported: {' '.join(SUPPORTED_WRITE)}"
        )
    output = _output(path, points, fields, normals, colors, source)
    directory = path.parent
    if not directory.is_dir():
        raise _write_error(path, f"the directory {directory} does not exist")
    try:
        _atomic_write(path, lambda stream: writer(stream, output, path))
    except OSError as exc:
        raise _write_error(path, exc.strerror or _one_line(exc)) from exc


def _new_file_mode(path: Path) -> int:
    """Permissions for the output: the replaced file's, else ``0o666`` minus the umask."""
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        pass
    umask = None
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("Umask:"):
                    umask = int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    if umask is None:
        umask = os.umask(0o022)
        os.umask(umask)
    return 0o666 & ~umask


def _atomic_write(path: Path, write) -> None:
    """Call ``write(stream)`` on a temporary file next to ``path``, then move it over ``path``.

    On any exception the temporary file is removed and the exception re-raised.
    """
    temporary = tempfile.NamedTemporaryFile(
        mode="w+b", delete=False, dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix
    )
    try:
        with temporary as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary.name, _new_file_mode(path))
        os.replace(temporary.name, path)
    except BaseException:
        try:
            os.unlink(temporary.name)
        except FileNotFoundError:
            pass
        raise


def _ordered_columns(output: _Output) -> dict:
    """All output properties by name, in the written order: x y z, normals, colours, fields."""
    columns = {axis: output.points[:, k] for k, axis in enumerate("xyz")}
    if output.normals is not None:
        columns.update({name: output.normals[:, k] for k, name in enumerate(_NORMAL_NAMES)})
    if output.colors is not None:
        columns.update({name: output.colors[:, k] for k, name in enumerate(_COLOR_NAMES)})
    columns.update(output.columns)
    return columns


def _ply_dtype(path, name: str, values: np.ndarray) -> np.dtype:
    """The PLY scalar type that holds ``values`` exactly (little endian)."""
    kind, size = values.dtype.kind, values.dtype.itemsize
    if kind == "b":
        return np.dtype("u1")
    if kind == "f":
        return np.dtype("<f8" if size > 4 else "<f4")
    code = f"{kind}{size}"
    if code in _PLY_TYPES:
        return np.dtype("<" + code)
    low, high = (int(values.min()), int(values.max())) if values.size else (0, 0)
    if np.iinfo(np.int32).min <= low and high <= np.iinfo(np.int32).max:
        return np.dtype("<i4")
    if 0 <= low and high <= np.iinfo(np.uint32).max:
        return np.dtype("<u4")
    if max(abs(low), abs(high)) <= 2**53:
        return np.dtype("<f8")
    raise _write_error(path, f"field {name!r} holds integers too large for PLY (beyond 2**53)")


def _write_ply(stream, output: _Output, path: Path) -> None:
    import plyfile

    columns = _ordered_columns(output)
    dtype = [(name, _ply_dtype(path, name, values)) for name, values in columns.items()]
    vertices = np.empty(output.points.shape[0], dtype=dtype)
    for name, values in columns.items():
        vertices[name] = values
    element = plyfile.PlyElement.describe(vertices, "vertex")
    plyfile.PlyData([element], text=False, byte_order="<", comments=["written by heatcurv"]).write(
        stream
    )


def _text_format(values: np.ndarray) -> str:
    # 17 significant digits for every float: float32 values too read back as the same float64
    return "%d" if values.dtype.kind in "biu" else "%.17g"


def _write_text(stream, output: _Output, path: Path, *, delimiter: str, comment: str) -> None:
    """One header line, then one line per point, formatted a block of rows at a time."""
    columns = _ordered_columns(output)
    stream.write((comment + delimiter.join(columns) + "\n").encode("utf-8"))
    row_format = delimiter.join(_text_format(values) for values in columns.values()) + "\n"
    n = output.points.shape[0]
    for start in range(0, n, _TEXT_BLOCK):
        stop = min(n, start + _TEXT_BLOCK)
        block = np.empty((stop - start, len(columns)), dtype=object)
        for k, values in enumerate(columns.values()):
            block[:, k] = values[start:stop].tolist()  # Python ints and floats
        text = (row_format * (stop - start)) % tuple(block.ravel().tolist())
        stream.write(text.encode("utf-8"))


def _write_csv(stream, output: _Output, path: Path) -> None:
    _write_text(stream, output, path, delimiter=",", comment="")


def _write_xyz(stream, output: _Output, path: Path) -> None:
    _write_text(stream, output, path, delimiter=" ", comment="# ")


def _write_npz(stream, output: _Output, path: Path) -> None:
    arrays = {"points": output.points}
    if output.normals is not None:
        arrays["normals"] = output.normals
    if output.colors is not None:
        arrays["colors"] = output.colors
    for name, values in output.arrays.items():
        if name in ("points", "xyz", "normals", "colors"):
            raise _write_error(path, f"field name {name!r} is reserved in NPZ output")
        arrays[name] = values
    # numpy's own .npz layout, written directly so that field names cannot clash
    # with np.savez's keyword arguments ("file", "allow_pickle")
    with zipfile.ZipFile(
        stream, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True
    ) as archive:
        for name, values in arrays.items():
            with archive.open(name + ".npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.ascontiguousarray(values), allow_pickle=False)


def _las_scales_offsets(points: np.ndarray):
    """Power-of-ten scale at most 1e-6 of the largest bounding-box side, round offsets.

    Returns
    -------
    scales, offsets : ndarray, shape (3,)
    """
    if points.shape[0] == 0:
        return np.full(3, 1e-3), np.zeros(3)
    low, high = points.min(axis=0), points.max(axis=0)
    extent = float(np.max(high - low))
    if not extent > 0:
        extent = max(1.0, float(np.abs(low).max()) * 1e-3)
    exponent = int(np.floor(np.log10(extent * 1e-6)))
    scale = 10.0**exponent
    unit = 10.0 ** (exponent + 6)  # a round number no larger than the extent
    offsets = np.floor(low / unit) * unit
    return np.full(3, scale), offsets


def _fits_exactly(values: np.ndarray, dtype: np.dtype) -> bool:
    """Whether ``values`` converts to ``dtype`` without changing any value."""
    if dtype.kind == "f":
        return True
    if values.dtype.kind == "f" and not _is_integral(values):
        return False
    if values.size == 0:
        return True
    info = np.iinfo(dtype)
    return info.min <= values.min() and values.max() <= info.max


def _write_las(stream, output: _Output, path: Path) -> None:
    import datetime

    import laspy

    points = output.points
    finite = np.isfinite(points).all(axis=1)
    if not finite.all():
        rows = np.flatnonzero(~finite)
        raise _write_error(
            path,
            "LAS cannot store NaN or infinite coordinates "
            f"({rows.size} row(s), first row {rows[0]})",
        )
    n = points.shape[0]
    source_header = output.source.meta.get("las_header") if output.source is not None else None
    if source_header is not None:
        header = source_header.copy()
        header.remove_extra_dims(list(header.point_format.extra_dimension_names))
        if output.colors is not None and "red" not in header.point_format.dimension_names:
            target = _LAS_WITH_RGB[header.point_format.id]
            version = str(header.version)
            if target == 5 and version < "1.3" or target in (7, 8, 10) and version < "1.4":
                version = "1.4"
            header.set_version_and_point_format(
                laspy.header.Version.from_str(version), laspy.PointFormat(target)
            )
        header.partial_reset()
        header.creation_date = datetime.date.today()
    else:
        header = laspy.LasHeader(point_format=7 if output.colors is not None else 6, version="1.4")
        header.scales, header.offsets = _las_scales_offsets(points)
    header.generating_software = "heatcurv"

    standard = set(header.point_format.dimension_names)
    extra = dict(output.columns)
    if output.normals is not None:
        extra = {**{name: output.normals[:, k] for k, name in enumerate(_NORMAL_NAMES)}, **extra}
    fill_standard = {}
    for name in list(extra):
        if name in standard:
            fill_standard[name] = extra.pop(name)
        elif len(name.encode("utf-8")) > 32:
            raise _write_error(path, f"field name {name!r} is longer than the 32 bytes LAS allows")
    params = []
    for name, values in extra.items():
        dtype = values.dtype
        if dtype.kind == "b":
            dtype = np.dtype(np.uint8)
        elif dtype.kind == "f" and dtype.itemsize < 4:
            dtype = np.dtype(np.float32)
        params.append(laspy.ExtraBytesParams(name=name, type=dtype))
    try:
        if params:
            header.add_extra_dims(params)
        las = laspy.LasData(
            header=header, points=laspy.ScaleAwarePointRecord.zeros(n, header=header)
        )
        las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    except OverflowError:
        raise _write_error(
            path,
            f"the coordinates do not fit the LAS scales {header.scales} "
            f"and offsets {header.offsets}",
        ) from None
    except Exception as exc:
        raise _write_error(path, f"laspy: {_one_line(exc)}") from None

    if output.colors is not None:
        rgb16 = output.source.meta.get("las_rgb16") if output.colors_from_source else None
        if rgb16 is None:
            rgb16 = output.colors.astype(np.uint16) * np.uint16(257)
        las.red, las.green, las.blue = rgb16[:, 0], rgb16[:, 1], rgb16[:, 2]
    for name, values in fill_standard.items():
        target = np.asarray(las[name]).dtype
        if not _fits_exactly(values, target):
            raise _write_error(
                path, f"field {name!r} does not fit the LAS dimension {name} ({target})"
            )
        try:
            las[name] = values.astype(target)
        except (OverflowError, ValueError) as exc:
            raise _write_error(
                path, f"field {name!r} does not fit the LAS dimension {name} ({_one_line(exc)})"
            ) from None
    for name, values in extra.items():
        las[name] = values.astype(np.uint8) if values.dtype.kind == "b" else values
    try:
        las.write(stream, do_compress=path.suffix.lower() == ".laz")
    except Exception as exc:
        raise _write_error(path, f"laspy: {_one_line(exc)}") from None


_WRITERS = {
    ".ply": _write_ply,
    ".las": _write_las,
    ".laz": _write_las,
    ".csv": _write_csv,
    ".xyz": _write_xyz,
    ".txt": _write_xyz,
    ".npz": _write_npz,
}
