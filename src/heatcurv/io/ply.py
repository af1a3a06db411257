"""PLY: ascii and binary reading with plyfile, binary little-endian writing.

The ``vertex`` element becomes the points and their properties; every other
element (faces, edges, ...), the comments and the ``obj_info`` lines are kept
in :attr:`PointCloud.meta` and written back when the cloud is the ``source``
of a PLY output.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import (
    PointCloud,
    _cloud_from_columns,
    _magic,
    _native,
    _one_line,
    _ordered_columns,
    _Output,
    _read_error,
    _write_error,
)

# plyfile's scalar types
_PLY_TYPES = {"i1", "u1", "i2", "u2", "i4", "u4", "f4", "f8"}


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
    meta = {"ply_comments": list(ply.comments), "ply_obj_info": list(ply.obj_info)}
    others = [element for element in ply.elements if element.name != "vertex"]
    if others:
        for element in others:  # in memory, not a map of the file (which may be replaced)
            element.data = np.array(element.data)
        meta["ply_elements"] = others
    if "face" in names:
        meta["faces"] = int(ply["face"].count)
    return _cloud_from_columns(columns, path, fmt, text_colours=False, meta=meta)


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
    coordinates = np.dtype(output.points_dtype).newbyteorder("<")
    dtype = [
        (name, coordinates if name in ("x", "y", "z") else _ply_dtype(path, name, values))
        for name, values in columns.items()
    ]
    vertices = np.empty(output.points.shape[0], dtype=dtype)
    for name, values in columns.items():
        vertices[name] = values
    elements = [plyfile.PlyElement.describe(vertices, "vertex")]
    meta = output.source.meta if output.source is not None else {}
    elements += meta.get("ply_elements", [])  # the source's faces and other elements
    comments = [c for c in meta.get("ply_comments", []) if c != "written by heatcurv"]
    plyfile.PlyData(
        elements,
        text=False,
        byte_order="<",
        comments=comments + ["written by heatcurv"],
        obj_info=list(meta.get("ply_obj_info", [])),
    ).write(stream)
