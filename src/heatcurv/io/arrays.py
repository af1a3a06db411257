"""NumPy files: NPY arrays (plain or structured) and NPZ archives, read; NPZ written.

An NPZ written by heatcurv holds ``points`` (n, 3) and one array of shape (n,)
per property, named as the other formats name their properties: ``nx ny nz``,
``red green blue``, the source's properties, then the fields (``mean``,
``d1x d1y d1z``, ...). Older archives, with ``normals`` (n, 3), ``colors``
(n, 3) and (n, 3) fields such as ``d1``, are read into the same names.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from ._common import (
    _COLOUR_NAMES,
    _NORMAL_NAMES,
    PointCloud,
    _cloud_from_columns,
    _colours_to_uint8,
    _magic,
    _native,
    _one_line,
    _ordered_columns,
    _Output,
    _read_error,
    _write_error,
)


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
        return _cloud_from_columns(columns, path, fmt, text_colours=False)
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
    return _cloud_from_columns(columns, path, fmt, text_colours=False)


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
    columns = {axis: _native(points[:, k]) for k, axis in enumerate("xyz")}
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
    for name, values in arrays.items():
        if values.dtype.kind not in "biuf" or values.ndim not in (1, 2) or values.shape[0] != n:
            continue  # not a per-point array (metadata): ignored
        if values.ndim == 1:
            columns.setdefault(name, _native(values))
        else:
            suffixes = "xyz" if values.shape[1] == 3 else [f"_{k}" for k in range(values.shape[1])]
            for k, suffix in enumerate(suffixes):
                columns.setdefault(f"{name}{suffix}", _native(values[:, k]))
    return _cloud_from_columns(columns, path, fmt, text_colours=False)


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
