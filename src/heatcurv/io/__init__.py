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
``.npz``                       ``points`` or ``xyz``     ``points`` + one array
                                                         per property
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
file of the same name stays as it was. Before writing,
:func:`~heatcurv.io.atomic.check_writable` refuses a missing or unwritable
directory and an existing read-only file (the command line calls it before
computing anything).

What is written
---------------
Computed values (the ``fields`` and ``normals`` given to :func:`write_points`)
are float32 in PLY, LAS/LAZ and NPZ by default: seven significant digits are
far below the error of any curvature estimate, and a LAZ of float64 fields is
two to three times larger (its compression does little for float noise).
``dtype="float64"`` (the command line's ``--float64``) keeps full precision.
Text formats always write float64 values with 17 significant digits. Booleans
(``reliable``, ``feature``) are written as 0/1 ``uint8``, 64-bit integers
(``neighbours``) as 32-bit integers where they fit.

The coordinates are never narrowed: LAS/LAZ from a LAS source keep its
integer coordinates, scales and offsets; PLY and NPZ write float32
coordinates only where the source stored float32 (or the given points are
float32) and the values are unchanged, float64 otherwise.

Every property of the ``source`` is written back with its stored type: PLY
properties, LAS standard and extra dimensions (an extra dimension keeps its
type, scale, offset and description; an array dimension read as
``name_0 name_1 ...`` is written as the array again), 16-bit and float
colours (16-bit PLY colours become LAS 16-bit colours and back), normals
(renamed ``nx ny nz``, in their stored float type), NPZ arrays. Only PLY list
properties of the ``vertex`` element are not read, hence not written.

Faces: a PLY source's other elements (``face``, ``edge``, ...) are written
back, unchanged, when the output is PLY (the points are written in the same
order, so the vertex indices stay valid), with its comments and ``obj_info``
lines. Where they cannot be kept -- a PLY mesh written to LAS/LAZ, text or
NPZ, or any OBJ or OFF mesh (heatcurv reads their vertices only) --
:func:`write_points` issues one :class:`~heatcurv.errors.HeatcurvWarning`
saying how many faces are not written (the command line prints it as one
``heatcurv: warning:`` line).

The readers and writers live in one module per format family: :mod:`.ply`,
:mod:`.las` (LAS/LAZ), :mod:`.text` (XYZ/TXT/CSV/PTS), :mod:`.meshes` (OBJ,
OFF), :mod:`.arrays` (NPY/NPZ); :mod:`.atomic` holds the atomic write. This
module holds the public API and the dispatch by extension.
"""

from __future__ import annotations

import warnings
import zipfile
import zlib
from pathlib import Path

from ..errors import HeatcurvError, HeatcurvWarning
from ._common import (
    PointCloud,
    _float_dtype,
    _one_line,
    _output,
    _read_error,
    _write_error,
)
from .arrays import _read_npy, _read_npz, _write_npz
from .atomic import atomic_write, check_writable
from .las import _read_las, _write_las
from .meshes import _read_obj, _read_off
from .ply import _read_ply, _write_ply
from .text import _read_text, _write_csv, _write_xyz

__all__ = [
    "PointCloud", "SUPPORTED_READ", "SUPPORTED_WRITE", "read_points", "write_points", "check_writable",
]


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
        ``colours`` (n, 3) uint8, every other per-point property in ``fields``.
        Rows holding NaN are kept as they are (``heatcurv.estimate`` reports
        them). PLY: the ``vertex`` element gives the points (its list
        properties are skipped); the other elements (faces) are kept in
        ``meta`` for :func:`write_points`. OBJ and OFF: the vertices; the
        faces are checked against them (see :mod:`heatcurv.io.meshes`) and
        counted in ``meta["faces"]``, not kept.

    Raises
    ------
    HeatcurvError
        If the file is missing or unreadable, its extension is not supported,
        it holds no points, it is truncated or not of the format its extension
        says, a text row has the wrong number of values or a non-number (the
        message gives the line), an OBJ or OFF face names a vertex the file
        does not have or an OFF file's lines do not match its counts, or it
        has no x, y, z coordinates.
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
    # what a reader's own checks did not foresee, in plain words (no traceback)
    except MemoryError:
        raise _read_error(path, "not enough memory to read it") from None
    except OverflowError as exc:
        raise _read_error(path, f"a count or value is too large ({_one_line(exc)})") from None
    except RecursionError:
        raise _read_error(path, "its structure is nested too deeply to read") from None
    except UnicodeError as exc:
        raise _read_error(path, f"it holds bytes that are not valid text ({_one_line(exc)})") from None
    except (zlib.error, zipfile.BadZipFile, EOFError) as exc:
        raise _read_error(path, f"damaged or truncated data ({_one_line(exc)})") from None


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


def write_points(
    path, points, fields=None, *, normals=None, colours=None, source=None, dtype=None
) -> None:
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
        ``d1x d1y d1z`` (in every format, NPZ too). Float fields are written
        as ``dtype``; booleans as 0/1 (``uint8``); 64-bit integers as 32-bit
        where they fit. A given field replaces a source property of the same
        name.
    normals : array_like, shape (n, 3), optional
        Written as ``nx ny nz``, as ``dtype``; default: ``source.normals``,
        in the float type the source stored them with.
    colours : array_like, shape (n, 3), integers 0-255, optional
        Written as ``red green blue`` (uint8; LAS 16-bit, ``value * 257``);
        default: ``source.colours``.
    source : PointCloud, optional
        The cloud the points came from: its ``fields`` are written back (and
        its normals and colours unless given). For LAS/LAZ output from a LAS
        source the header's point format, version, scales, offsets and
        records (CRS) are kept and 16-bit colours written unchanged.
    dtype : {None, "float32", "float64"}, optional
        Type of the float ``fields`` and ``normals`` given. Default (None):
        float32 for ``.ply``, ``.las``, ``.laz`` and ``.npz``, float64 for the
        text formats; a field float32 cannot hold (magnitudes beyond 3.4e38
        or non-zero below 1.2e-38: the curvatures and areas of a cloud in
        extreme units) is then written as float64, and with an explicit
        ``"float32"`` it is an error. The coordinates and the ``source``'s properties keep
        their own types (see the notes of :mod:`heatcurv.io`).

    Warns
    -----
    HeatcurvWarning
        When ``source`` is a mesh whose faces are not written: a PLY with a
        ``face`` element written to another format, or an OBJ or OFF mesh.

    Notes
    -----
    Property order: ``x y z``, ``nx ny nz``, ``red green blue``, the source's
    fields, the given fields.

    ``.ply``: binary little endian, ``x y z`` as double (float where the
    source stored float and the values are unchanged); other properties keep
    their dtype (int64 values become int32/uint32 where they fit, else
    double; float16 becomes float); a PLY source's faces and other elements,
    comments and ``obj_info`` follow the vertices.
    ``.las``/``.laz``: LAS 1.4 point format 6 (7 with colours) unless the
    source is LAS; fields named like a standard dimension of the point format
    (``intensity``, ``classification``, ...) fill it when their values fit
    exactly, the others become extra-bytes dimensions (names of at most 32
    characters). Scales are a power of ten at most 1e-6 of the largest
    bounding-box side.
    ``.csv``: comma-separated with a header line; ``.xyz``/``.txt``:
    space-separated with a ``# x y z ...`` header line. Floats are written
    with 17 significant digits (``%.17g``), so they read back exactly.
    ``.npz``: an array ``points`` (n, 3) and one array (n,) per property,
    named as in the other formats: ``nx ny nz``, ``red green blue``, the
    source's properties, the fields (``d1x d1y d1z``, ...). Archives of
    earlier versions (``normals``, ``colors``, (n, 3) fields) are still read.

    Raises
    ------
    HeatcurvError
        On an unsupported extension, arrays that do not have one row per
        point, unusable or repeated field names, values the format cannot
        hold (NaN coordinates in LAS, fields that do not fit a standard LAS
        dimension), a ``dtype`` other than float32 or float64, or an OS error
        (missing or read-only directory, read-only existing file).
    """
    path = Path(path)
    ext = path.suffix.lower()
    writer = _WRITERS.get(ext)
    if writer is None:
        raise _write_error(
            path, f"unknown extension {ext or '(none)'!r}; supported: {' '.join(SUPPORTED_WRITE)}"
        )
    float_dtype = _float_dtype(path, dtype, ext)
    output = _output(path, points, fields, normals, colours, source, float_dtype, explicit=dtype is not None)
    check_writable(path)
    try:
        atomic_write(path, lambda stream: writer(stream, output, path))
    except OSError as exc:
        raise _write_error(path, exc.strerror or _one_line(exc)) from exc
    dropped = _unwritten_faces(source, path)
    if dropped:
        warnings.warn(HeatcurvWarning(dropped), stacklevel=2)


def _unwritten_faces(source, path) -> str | None:
    """Why the faces of ``source`` would not be in a file written to ``path``, or None if they would.

    Parameters
    ----------
    source : PointCloud or None
        The cloud read (its ``meta`` says whether it had faces).
    path : str or os.PathLike
        The output file; PLY keeps a PLY source's faces.

    Returns
    -------
    str or None
        A one-line message, e.g. ``the 2000 faces of mesh.ply are not written
        to out.laz (.laz holds points only; write a .ply to keep them)``.
    """
    if source is None:
        return None
    meta = source.meta
    count = int(meta.get("faces") or 0)
    elements = meta.get("ply_elements") or []
    ext = Path(path).suffix.lower()
    if ext == ".ply" and elements:
        return None  # written back
    if not count and not elements:
        return None
    named = source.path if source.path is not None else "the source"
    if count:
        what = f"the {count} faces of {named}"
        others = [e for e in elements if e.name != "face"]
        if others:
            what += " (and its PLY elements " + ", ".join(f"{e.name} ({e.count})" for e in others) + ")"
    else:
        what = "the PLY elements " + ", ".join(f"{e.name} ({e.count})" for e in elements) + f" of {named}"
    if elements:
        why = f"{ext} holds points only; write a .ply to keep them"
    else:
        why = f"heatcurv reads only the vertices of {(source.format or 'mesh').upper()} files"
    return f"{what} are not written to {path} ({why})"


_WRITERS = {
    ".ply": _write_ply,
    ".las": _write_las,
    ".laz": _write_las,
    ".csv": _write_csv,
    ".xyz": _write_xyz,
    ".txt": _write_xyz,
    ".npz": _write_npz,
}
