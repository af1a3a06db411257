"""Mesh files read as point clouds: the vertices of OBJ (``v`` lines) and ASCII OFF.

The faces are not read; their number is ``meta["faces"]``, so that a writer
can say they are not written.
"""

from __future__ import annotations

import io as _stdio
import re
from pathlib import Path

import numpy as np

from ._common import (
    _COLOUR_NAMES,
    _NORMAL_NAMES,
    PointCloud,
    _cloud_from_columns,
    _colours_to_uint8,
    _is_integral,
    _read_error,
)
from ._textparse import _decode_text, _first_bad_line, _iter_lines, _load_table, _strip_comment


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
    names = {3: ["x", "y", "z"], 4: ["x", "y", "z", "w"], 6: ["x", "y", "z", *_COLOUR_NAMES]}[ncols]
    columns = {name: np.ascontiguousarray(table[:, k]) for k, name in enumerate(names)}
    faces = len(re.findall(r"(?m)^[ \t]*f[ \t]", text))
    return _cloud_from_columns(
        columns, path, fmt, text_colours=False, meta={"faces": faces} if faces else None
    )


def _obj_line_number(text: str, vertex_index: int) -> int:
    """Line number in the file of the ``vertex_index``-th ``v`` line (error path only)."""
    for index, match in enumerate(re.finditer(r"(?m)^[ \t]*v[ \t]+", text)):
        if index == vertex_index:
            return text.count("\n", 0, match.start()) + 1
    return 0


def _off_count(path: Path, tokens: list, index: int, what: str, line: int) -> int:
    """The ``index``-th count of an OFF header (0 if absent): a non-negative integer."""
    if len(tokens) <= index:
        return 0
    token = tokens[index]
    if not re.fullmatch(r"[+-]?\d+", token):
        raise _read_error(path, f"line {line}: {token!r} is not a {what} count (a whole number)")
    if len(token) > 4000:  # Python refuses to convert more than 4300 digits to an int
        raise _read_error(path, f"line {line}: the {what} count has {len(token)} digits")
    count = int(token)
    if count < 0:
        raise _read_error(path, f"line {line}: the {what} count {count} is negative")
    return count


def _line_start(text: str, number: int) -> int:
    """Offset in ``text`` of the start of line ``number`` (1-based; ``len(text)`` past the end)."""
    start = 0
    for _ in range(number - 1):
        end = text.find("\n", start)
        if end < 0:
            return len(text)
        start = end + 1
    return start


def _read_off(path: Path, fmt: str) -> PointCloud:
    text = _decode_text(path)
    lines = _iter_lines(text)
    keyword = None
    tokens = []
    counts_line = 0
    for number, line in lines:
        content = line.split("#", 1)[0].strip()
        if content:
            counts_line = number
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
    while len(tokens) < 1:
        try:
            counts_line, line = next(lines)
        except StopIteration:
            raise _read_error(path, "the OFF header has no vertex count") from None
        tokens = line.split("#", 1)[0].split()
    n_vertices = _off_count(path, tokens, 0, "vertex", counts_line)
    if n_vertices == 0:
        raise _read_error(path, "the file holds no points")
    n_faces = _off_count(path, tokens, 1, "face", counts_line)
    # every vertex and face takes a line: counts the file cannot hold are refused before
    # anything is allocated for them (lines counted loosely: blank and comment lines too)
    rest = _line_start(text, counts_line + 1)
    available = text.count("\n", rest) + (0 if text.endswith("\n") or rest >= len(text) else 1)
    if n_vertices > available:
        raise _read_error(
            path,
            f"truncated: the header announces {n_vertices} vertices, the file has "
            f"{available} line{'' if available == 1 else 's'} after line {counts_line}",
        )
    if n_faces > available - n_vertices:
        raise _read_error(
            path,
            f"the header announces {n_faces} face{'' if n_faces == 1 else 's'}, the file has "
            f"{available - n_vertices} line{'' if available - n_vertices == 1 else 's'} "
            f"after its {n_vertices} vertices",
        )

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

    has_texture, has_colour, has_normal = (bool(match.group(k)) for k in (1, 2, 3))
    n_colour = ncols - 3 - 3 * has_normal - 2 * has_texture
    if (has_colour and n_colour not in (3, 4)) or (not has_colour and n_colour != 0):
        raise _read_error(path, f"line {first[0]}: {ncols} values do not match a {keyword} vertex")
    names = ["x", "y", "z"] + (list(_NORMAL_NAMES) if has_normal else [])
    columns = {name: np.ascontiguousarray(table[:, k]) for k, name in enumerate(names)}
    cloud = _cloud_from_columns(
        columns, path, fmt, text_colours=False, meta={"faces": n_faces} if n_faces else None
    )
    if has_colour:
        start = len(names)
        rgba = table[:, start : start + n_colour]
        # Geomview colours are floats 0-1, MeshLab writes integers 0-255 (alpha included)
        as_bytes = _is_integral(rgba) and rgba.max(initial=0) > 1
        cloud.colours = _colours_to_uint8(rgba[:, :3], text=as_bytes)
        if cloud.colours is None:
            raise _read_error(path, "vertex colours are neither 0-255 integers nor 0-1 fractions")
        if not np.array_equal(cloud.colours, rgba[:, :3]):
            cloud.meta["colour_values"] = np.ascontiguousarray(rgba[:, :3])  # 0-1 fractions
        if n_colour == 4:
            cloud.fields["alpha"] = np.ascontiguousarray(rgba[:, 3])
    if has_texture:
        start = ncols - 2
        cloud.fields["s"] = np.ascontiguousarray(table[:, start])
        cloud.fields["t"] = np.ascontiguousarray(table[:, start + 1])
    return cloud
