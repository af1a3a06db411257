"""PLY: ascii and binary reading with plyfile, binary little-endian writing.

The ``vertex`` element becomes the points and their properties; every other
element (faces, edges, ...), the comments and the ``obj_info`` lines are kept
in :attr:`PointCloud.meta` and written back when the cloud is the ``source``
of a PLY output.

Untrusted files: the header is parsed first (its ``end_header`` within the first
MiB) and its element counts checked against the file's size before plyfile
allocates anything (see :func:`_check_ply_size`); a binary file must end where
its last element ends.
"""

from __future__ import annotations

import errno
import io as _stdio
from pathlib import Path

import numpy as np

from ._common import (
    PointCloud,
    _brief,
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


# bytes searched for the 'end_header' line; plyfile parses a header a byte at a time
# (about 2 s per MiB), and real headers (comments included) are a few kB
_HEADER_LIMIT = 1 << 20
_PLURALS = {"vertex": "vertices", "face": "faces", "edge": "edges"}


def _ply_header(path: Path, size: int):
    """The parsed header (:class:`plyfile.PlyData` without data) and its length in bytes."""
    import plyfile

    with open(path, "rb") as stream:
        head = stream.read(min(size, _HEADER_LIMIT))
    if b"end_header" not in head:
        if size > _HEADER_LIMIT:
            problem = f"no 'end_header' line in its first {_HEADER_LIMIT >> 10} KiB"
        else:
            problem = "the header has no 'end_header' line"
        raise _read_error(path, f"not a valid PLY file ({problem})")
    buffer = _stdio.BytesIO(head)
    try:
        header = plyfile.PlyData._parse_header(buffer)
    except UnicodeDecodeError:
        at = buffer.tell() - 1
        line = head.count(b"\n", 0, at) + 1
        raise _read_error(
            path, f"not a valid PLY file (header line {line} holds the non-ASCII byte 0x{head[at]:02x})"
        ) from None
    except (plyfile.PlyParseError, ValueError, TypeError) as exc:
        raise _read_error(path, f"not a valid PLY file ({_brief(exc)})") from None
    return header, buffer.tell()


def _element_text(element, size_text: str) -> str:
    """``120 vertices of 27 bytes``: an element's count, name and record size in words."""
    count, name = element.count, element.name
    noun = name if count == 1 else _PLURALS.get(name, f"'{name}' elements")
    if count == 1 and name not in _PLURALS:
        noun = f"'{name}' element"
    return f"{count} {noun} of {size_text}"


def _check_ply_size(path: Path, header, header_size: int, size: int) -> None:
    """Refuse element counts the file cannot hold, before anything is allocated for them.

    Binary: an element of fixed-size records needs exactly ``count * record`` bytes,
    so the file must hold exactly the header plus every element. A list property
    needs at least its length field, which gives a lower bound. ASCII: every value
    takes at least two characters (a digit and a separator).
    """
    import plyfile

    body = size - header_size
    for element in header.elements:
        if element.count < 0:
            raise _read_error(
                path, f"the header's element {element.name!r} has a negative count ({element.count})"
            )
    parts, needed, exact = [], 0, True
    for element in header.elements:
        if header.text:
            values = len(element.properties)
            needed += element.count * max(1, 2 * values)
            continue
        record = 0
        for prop in element.properties:
            if isinstance(prop, plyfile.PlyListProperty):
                exact = False
                record += np.dtype(prop.list_dtype(header.byte_order)[0]).itemsize
            else:
                record += np.dtype(prop.dtype(header.byte_order)).itemsize
        lists = any(isinstance(prop, plyfile.PlyListProperty) for prop in element.properties)
        parts.append(_element_text(element, f"{'at least ' if lists else ''}{record} bytes"))
        needed += element.count * record
    if header.text:
        if needed - 1 > body:  # the last line end may be missing
            counts = " and ".join(_element_text(e, f"{len(e.properties)} values") for e in header.elements)
            raise _read_error(
                path,
                f"the header announces {counts} (at least {needed - 1} bytes of text) after the "
                f"header, the file holds {body}",
            )
        return
    if needed > body or (exact and needed != body):
        announced = " and ".join(parts)
        least = "" if exact else "at least "
        raise _read_error(
            path,
            f"the header announces {announced} ({least}{needed} bytes) after the header, "
            f"the file holds {body}",
        )


class _BoundedReads:
    """A binary file whose ``read(n)`` never asks for more than the bytes left in the file.

    plyfile reads a list property row by row as ``stream.read(count * itemsize)`` with the
    count taken from the file: a corrupt count of 2**32 made the buffered reader allocate
    16 GiB for one row before finding the end of the file (a MemoryError under a memory
    limit, a huge allocation without one). Everything else is the file's own.
    """

    def __init__(self, stream, size: int):
        self._stream, self._size = stream, size

    def read(self, n: int = -1) -> bytes:
        if n is not None and n >= 0:
            n = min(n, max(self._size - self._stream.tell(), 0))
        return self._stream.read(n)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _read_body(path: Path, known_list_len: dict):
    """The whole file read by plyfile, and where its last element ended (binary files)."""
    import plyfile

    with open(path, "rb") as raw:
        stream = _BoundedReads(raw, path.stat().st_size)
        ply = plyfile.PlyData.read(stream, mmap="c", known_list_len=known_list_len)
        # (an ASCII file's text wrapper, gone with the read, has closed the stream)
        return ply, None if ply.text else stream.tell()


def _read_ply(path: Path, fmt: str) -> PointCloud:
    import plyfile

    if _magic(path, 3) != b"ply":
        raise _read_error(path, "not a valid PLY file (it does not start with 'ply')")
    size = path.stat().st_size
    header, header_size = _ply_header(path, size)
    _check_ply_size(path, header, header_size, size)
    try:
        # First with triangle faces of known length, memory-mapped (fast for big meshes);
        # on any failure (other face sizes, ...) without them: the vertices are still
        # mapped, the faces read a row at a time, and that read's error is the one reported.
        try:
            ply, end = _read_body(path, {"face": {"vertex_indices": 3, "vertex_index": 3}})
        except Exception:
            ply, end = _read_body(path, {})
    except OSError as exc:
        if exc.errno is not None and exc.errno != errno.EINVAL:
            raise  # a real I/O error
        raise _read_error(path, f"not a valid PLY file ({_one_line(exc)})") from None
    except UnicodeDecodeError as exc:
        byte = exc.object[exc.start] if exc.start < len(exc.object) else 0
        raise _read_error(
            path, f"not a valid PLY file (the ASCII data holds the non-ASCII byte 0x{byte:02x})"
        ) from None
    except Exception as exc:  # plyfile raises parse and value errors
        raise _read_error(path, f"not a valid PLY file ({_brief(exc)})") from None
    if not ply.text and end != size:
        raise _read_error(
            path,
            f"trailing bytes after the last element: the elements end at byte {end}, "
            f"the file holds {size}",
        )

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
