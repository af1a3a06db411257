"""NumPy files: NPY arrays (plain or structured) and NPZ archives, read; NPZ written.

An NPZ written by heatcurv holds ``points`` (n, 3) and one array of shape (n,)
per property, named as the other formats name their properties: ``nx ny nz``,
``red green blue``, the source's properties, then the fields (``mean``,
``d1x d1y d1z``, ...). Older archives, with ``normals`` (n, 3), ``colors``
(n, 3) and (n, 3) fields such as ``d1``, are read into the same names.

Untrusted files: an NPY array's shape times its item size must equal the bytes
after its header. An NPZ's zip directory is checked before anything is
decompressed (:func:`_npz_members`: ratio, total and memory bounds), each
``.npy`` member's header against its declared size, and members are read a
chunk at a time into their array (the CRC checked); members that are not
``.npy`` arrays are skipped, pickled object arrays are never loaded.
"""

from __future__ import annotations

import errno
import math
import os
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

try:
    from lzma import LZMAError
except ImportError:  # pragma: no cover - Python built without lzma
    LZMAError = zlib.error

from ..errors import HeatcurvError
from ._common import (
    _COLOUR_NAMES,
    _NORMAL_NAMES,
    PointCloud,
    _brief,
    _cloud_from_columns,
    _colours_to_uint8,
    _magic,
    _native,
    _one_line,
    _ordered_columns,
    _Output,
    _quoted,
    _read_error,
    _size_text,
    _write_error,
)

# An archive member may declare at most this many bytes per compressed byte. Deflate (the
# only compression numpy writes) cannot exceed about 1032:1 (a 258-byte match costs at least
# two bits); numpy's savez_compressed of a constant array reaches 1025-1028:1. 1100 refuses
# nothing numpy can write and bounds the whole archive too, so members that share (overlap)
# compressed data cannot multiply it. Bzip2 and LZMA members, which numpy never writes, are
# held to the same bound.
_MAX_RATIO = 1100
# The arrays of a whole archive may declare at most this many bytes per byte of the file. A
# point cloud's arrays compress far less than a constant array: float coordinates 1.1-2:1,
# and an archive with twenty constant float64 fields beside its points about 8:1 overall
# (heatcurv writes them uncompressed, 1:1). 200:1 over the archive leaves every such file,
# while a bomb of zeros (1000:1) of 261 kB can no longer inflate to 256 MiB (measured by
# the fuzz suite: 768 MiB of peak memory, three copies).
_MAX_ARCHIVE_RATIO = 200
# bytes any member or archive may declare beyond the ratio: an .npy header of a small array
# compresses poorly, and a few kB of arrays are harmless whatever they claim
_RATIO_SLACK = 1 << 16
# an archive is read only if this many times its arrays' bytes fit in the memory available:
# the arrays, their per-column native copies, and the float64 points assembled from them
_PEAK_FACTOR = 3
# bytes decompressed per read: the only memory beyond the array being filled
_CHUNK = 1 << 20


def _memory_budget() -> int | None:
    """Bytes a reader can still allocate, or None if unknown.

    The smaller of the memory available (Linux: ``MemAvailable`` plus free swap;
    elsewhere the free physical pages) and, under an address-space limit
    (``ulimit -v``, ``RLIMIT_AS``), what is left of it.
    """
    budgets = []
    try:
        with open("/proc/meminfo") as stream:
            info = {line.split(":")[0]: int(line.split()[1]) * 1024 for line in stream if line.strip()}
        if "MemAvailable" in info:
            budgets.append(info["MemAvailable"] + info.get("SwapFree", 0))
    except (OSError, ValueError, IndexError):
        try:
            budgets.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (AttributeError, ValueError, OSError):
            pass
    try:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        if limit != resource.RLIM_INFINITY:
            used = 0
            with open("/proc/self/status") as stream:
                for line in stream:
                    if line.startswith("VmSize:"):
                        used = int(line.split()[1]) * 1024
            budgets.append(max(limit - used, 0))
    except (ImportError, OSError, ValueError, IndexError):
        pass
    return min(budgets) if budgets else None


class _Counting:
    """A read-only stream that counts the bytes read (the size of an .npy header)."""

    def __init__(self, stream):
        self.stream, self.count = stream, 0

    def read(self, size=-1):
        data = self.stream.read(size)
        self.count += len(data)
        return data


def _npy_header(path, stream, invalid):
    """``(shape, fortran_order, dtype, header_bytes)`` of the .npy data at the start of ``stream``.

    ``invalid`` turns a problem into the message, e.g. ``not a valid NPY file (problem)``.
    """
    counting = _Counting(stream)
    fmt = np.lib.format
    problem = None
    try:
        version = fmt.read_magic(counting)
        if version == (1, 0):
            shape, fortran, dtype = fmt.read_array_header_1_0(counting)
        elif version in ((2, 0), (3, 0)):  # 3.0 differs only in allowing UTF-8 field names
            shape, fortran, dtype = fmt.read_array_header_2_0(counting)
        else:
            problem = f"unknown format version {version[0]}.{version[1]}"
    except (zipfile.BadZipFile, zlib.error, LZMAError, EOFError, OSError):
        raise  # the archive's, not the header's (see _read_npz)
    except RecursionError:
        problem = "the header is nested too deeply"
    except MemoryError:
        problem = "the header is too large"
    except UnicodeError:
        problem = "the header is not ASCII text"
    except Exception as exc:  # numpy's literal_eval of untrusted text: value, syntax, token errors
        problem = _brief(exc)
        # numpy quotes the header, tokenize a tuple, ast names its node objects
        if problem.startswith(("Cannot parse header", "(", "malformed node or string")):
            problem = "the header is not a Python dictionary literal"
    if problem is None and any(d < 0 for d in shape):
        problem = f"the header's shape {shape} has a negative dimension"
    if problem is None and dtype.itemsize == 0:
        problem = f"the header's dtype {dtype} has no bytes"
    if problem is not None:
        raise _read_error(path, invalid(problem))
    return shape, fortran, dtype, counting.count


def _shape_text(shape, dtype) -> str:
    return f"shape {tuple(shape)} {dtype}"


def _read_npy(path: Path, fmt: str) -> PointCloud:
    if _magic(path, 6) != b"\x93NUMPY":
        raise _read_error(path, "not a valid NPY file (no NumPy array header)")
    size = path.stat().st_size
    with open(path, "rb") as stream:
        shape, fortran, dtype, header = _npy_header(
            path, stream, lambda problem: f"not a valid NPY file ({problem})"
        )
        if dtype.hasobject:
            raise _read_error(path, "the array holds Python objects, not numbers")
        count = math.prod(shape)
        needed = count * dtype.itemsize
        if needed != size - header:
            raise _read_error(
                path,
                f"the header announces an array of {_shape_text(shape, dtype)} "
                f"({needed} bytes) after the header, the file holds {size - header}",
            )
        try:
            array = np.fromfile(stream, dtype=dtype, count=count)
        except (ValueError, OSError) as exc:
            raise _read_error(path, f"not a valid NPY file ({_one_line(exc)})") from None
    if array.size != count:  # the file changed while read
        raise _read_error(path, f"truncated: {array.size} of {count} values read")
    array = array.reshape(shape[::-1]).transpose() if fortran else array.reshape(shape)
    if array.dtype.names:
        if array.ndim != 1:
            raise _read_error(path, f"a structured array must have shape (n,), got {array.shape}")
        columns = {
            name: _native(array[name]) for name in array.dtype.names if array[name].ndim == 1
        }
        return _cloud_from_columns(columns, path, fmt, text_colours=False)
    if array.dtype.kind == "b":
        raise _read_error(path, "the array holds booleans (a mask?), not coordinates")
    if array.dtype.kind not in "iuf":
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
    return _cloud_from_columns(columns, path, fmt, text_colours=False)


def _npz_members(path: Path, archive: zipfile.ZipFile, size: int) -> list:
    """The archive's ``.npy`` members to load, checked against the file before anything is read.

    Other members (``meta.json``, a README, directories) are skipped. Each member's
    declared size is held to :data:`_MAX_RATIO` times its compressed size, the sum to
    :data:`_MAX_ARCHIVE_RATIO` times the file's size and to the memory available.
    """
    members = []
    for info in archive.infolist():
        name = info.filename
        if not name.endswith(".npy"):  # also directories; not is_dir(): a name may be empty
            continue
        if info.flag_bits & 0x1:
            raise _read_error(path, f"member {_quoted(name)} is encrypted")
        if info.compress_type == zipfile.ZIP_STORED and info.file_size != info.compress_size:
            raise _read_error(
                path,
                f"member {_quoted(name)} is stored uncompressed in {info.compress_size} bytes "
                f"but declares {info.file_size}",
            )
        if info.file_size > _MAX_RATIO * info.compress_size + _RATIO_SLACK:
            raise _read_error(
                path,
                f"member {_quoted(name)} declares {_size_text(info.file_size)} uncompressed from "
                f"{_size_text(info.compress_size)} ({info.file_size // max(info.compress_size, 1)}:1; "
                f"at most {_MAX_RATIO}:1 is read): a zip bomb or a damaged archive",
            )
        members.append(info)
    total = sum(info.file_size for info in members)
    if total > _MAX_ARCHIVE_RATIO * size + _RATIO_SLACK:
        raise _read_error(
            path,
            f"the arrays declare {_size_text(total)} uncompressed in a file of "
            f"{_size_text(size)} (more than {_MAX_ARCHIVE_RATIO}:1 over the archive, far beyond what a "
            "point cloud's arrays compress to): a zip bomb or a damaged archive",
        )
    budget = _memory_budget()
    if budget is not None and _PEAK_FACTOR * total > budget:
        raise _read_error(
            path,
            f"the arrays need {_size_text(total)} once decompressed (about "
            f"{_size_text(_PEAK_FACTOR * total)} while read), more than the "
            f"{_size_text(budget)} of memory available",
        )
    return members


def _read_member(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo):
    """One ``.npy`` member as an array (read a chunk at a time into it), or None if it holds objects."""
    where = f"member {_quoted(info.filename)}"
    try:
        member = archive.open(info)
    except NotImplementedError:
        raise _read_error(
            path, f"{where} uses compression method {info.compress_type}, which cannot be read"
        ) from None
    with member:
        shape, fortran, dtype, header = _npy_header(
            path, member, lambda problem: f"{where} is not a valid NPY array ({problem})"
        )
        if dtype.hasobject:
            return None  # pickled Python objects: never loaded
        count = math.prod(shape)
        needed = count * dtype.itemsize
        if needed != info.file_size - header:
            raise _read_error(
                path,
                f"{where}: the header announces an array of {_shape_text(shape, dtype)} "
                f"({needed} bytes) after the header, the archive's directory declares "
                f"{info.file_size - header}",
            )
        array = np.empty(count, dtype=dtype)
        raw = array.view(np.uint8).reshape(-1)
        done = 0
        while done < needed:
            chunk = member.read(min(_CHUNK, needed - done))
            if not chunk:
                raise _read_error(
                    path, f"{where} is truncated: {done} of {needed} data bytes decompressed"
                )
            raw[done : done + len(chunk)] = np.frombuffer(chunk, dtype=np.uint8)
            done += len(chunk)
        if member.read(1):  # pragma: no cover - zipfile stops at the declared size
            raise _read_error(path, f"{where} holds more than its declared size")
    return array.reshape(shape[::-1]).transpose() if fortran else array.reshape(shape)


#: Numeric NPZ members of at most this many rows (an offset, a viewpoint, a 4 x 4 transform) are
#: metadata, ignored; longer ones are per-point arrays and must have one row per point.
_NPZ_METADATA_ROWS = 4


def _read_npz(path: Path, fmt: str) -> PointCloud:
    if _magic(path, 4) not in (b"PK\x03\x04", b"PK\x05\x06"):
        raise _read_error(path, "not a valid NPZ file (not a zip archive of NumPy arrays)")
    arrays, pickled = _npz_arrays(path)
    key = "points" if "points" in arrays else "xyz" if "xyz" in arrays else None
    if key is None:
        held = [name for name in ("points", "xyz") if name in pickled]
        if held:
            raise _read_error(path, f"'{held[0]}' holds Python objects (pickled), not numbers")
        raise _read_error(
            path, f"no 'points' or 'xyz' array (arrays: {', '.join(arrays) or 'none'})"
        )
    points = arrays.pop(key)
    if points.dtype.kind not in "iuf" or points.ndim != 2 or points.shape[1] != 3:
        raise _read_error(
            path,
            f"'{key}' has shape {points.shape} and dtype {points.dtype}; expected (n, 3) numbers",
        )
    n = points.shape[0]
    if n == 0:
        raise _read_error(path, "the file holds no points")
    columns = {axis: _native(points[:, k]) for k, axis in enumerate("xyz")}
    columns.update(_npz_normals_and_colours(path, arrays, n))
    for name, values in arrays.items():
        if values.dtype.kind not in "biuf" or values.ndim not in (1, 2) or values.shape[0] <= _NPZ_METADATA_ROWS < n:
            continue  # not a per-point array (a scalar, text, an offset or a small transform): ignored
        if values.shape[0] != n:
            raise _read_error(
                path, f"'{name}' has {values.shape[0]} rows but '{key}' has {n}: every per-point array of an "
                "NPZ cloud must have one row per point (a truncated or mismatched member)"
            )
        if values.ndim == 1:
            columns.setdefault(name, _native(values))
        else:
            suffixes = "xyz" if values.shape[1] == 3 else [f"_{k}" for k in range(values.shape[1])]
            for k, suffix in enumerate(suffixes):
                columns.setdefault(f"{name}{suffix}", _native(values[:, k]))
    return _cloud_from_columns(columns, path, fmt, text_colours=False)


def _npz_arrays(path: Path) -> tuple[dict, list]:
    """The archive's numeric arrays by name, and the names of its pickled members; damage is a one-line error."""
    size = path.stat().st_size
    arrays, pickled = {}, []
    try:
        with zipfile.ZipFile(path) as archive:
            for info in _npz_members(path, archive, size):
                array = _read_member(path, archive, info)
                key = info.filename[: -len(".npy")]
                if array is None:
                    pickled.append(key)
                else:
                    arrays[key] = array
    except HeatcurvError:
        raise
    except zipfile.BadZipFile as exc:
        problem = _brief(exc)
        if problem.startswith("Bad CRC-32"):
            problem = problem.replace("Bad CRC-32 for file", "the CRC-32 check fails for member")
        raise _read_error(path, f"not a valid NPZ file ({problem})") from None
    except zlib.error as exc:
        raise _read_error(path, f"not a valid NPZ file (damaged compressed data: {_brief(exc)})") from None
    except (EOFError, ValueError, struct.error, UnicodeError, LZMAError) as exc:
        raise _read_error(path, f"not a valid NPZ file (damaged archive: {_brief(exc)})") from None
    except NotImplementedError as exc:  # zipfile: a version or compression it cannot read
        raise _read_error(path, f"not a valid NPZ file (unsupported zip feature: {_brief(exc)})") from None
    except OSError as exc:
        if exc.errno == errno.EINVAL:  # a seek before the start of the file
            problem = "an offset in the zip directory points outside the file"
        elif exc.errno is None:  # bz2's damaged-data error
            problem = f"damaged compressed data: {_brief(exc)}"
        else:
            raise  # a real I/O error
        raise _read_error(path, f"not a valid NPZ file ({problem})") from None
    return arrays, pickled


def _npz_normals_and_colours(path: Path, arrays: dict, n: int) -> dict:
    """The columns of the ``normals`` and ``colors`` arrays (taken out of ``arrays``), checked against ``n`` points."""
    columns = {}
    normals = arrays.pop("normals", None)  # archives of earlier heatcurv versions (now nx ny nz)
    if normals is not None:
        if normals.dtype.kind not in "biuf" or normals.shape != (n, 3):
            raise _read_error(
                path, f"'normals' has shape {normals.shape}; expected ({n}, 3) like the points"
            )
        columns.update({name: _native(normals[:, k]) for k, name in enumerate(_NORMAL_NAMES)})
    colours = arrays.pop("colors", None)
    if colours is not None:
        converted = _colours_to_uint8(colours, text=False) if colours.shape == (n, 3) else None
        if converted is None:
            raise _read_error(
                path,
                f"'colors' (shape {colours.shape}, dtype {colours.dtype}) "
                f"are not ({n}, 3) RGB values",
            )
        columns.update({name: _native(colours[:, k]) for k, name in enumerate(_COLOUR_NAMES)})
    return columns


def _write_npz(stream, output: _Output, path: Path) -> None:
    arrays = {"points": output.points.astype(output.points_dtype, copy=False)}
    columns = _ordered_columns(output)
    for axis in "xyz":
        del columns[axis]
    for name, values in columns.items():
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
