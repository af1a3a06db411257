"""Mesh files read as point clouds: the vertices of OBJ (``v`` lines) and ASCII OFF.

The faces are checked, not kept: their number is ``meta["faces"]``, so that a
writer can say they are not written.

OFF (Geomview's format; ``OFF``, ``COFF``, ``NOFF``, ``STOFF`` and their
combinations): the keyword, then ``nv nf ne`` (on the keyword's line or the
next one that is not blank), then ``nv`` vertex lines and ``nf`` face lines
``k i1 .. ik`` followed by nothing, a colour-map index or an RGB(A) colour;
``#`` comments and blank lines may stand anywhere. The edge count ``ne`` is
ignored, as real files often give 0 or a wrong number. A file whose lines do
not match its counts -- a vertex line with another number of values, a vertex
count lower or higher than the vertex lines, a face count that does not match,
a face whose indices are not whole numbers from 0 to ``nv - 1``, a line left
over -- is refused, the message naming the line.

OBJ: ``v`` lines are the vertices; each ``f`` line's corners (``i``, ``i/t``,
``i//n``, ``i/t/n``; negative indices count back from the last ``v`` line
before the face) must name one of them. Texture and normal indices are not
checked, and other statements (``vn``, ``vt``, ``g``, ``usemtl``, ...) are
ignored.

Both are parsed by NumPy, not line by line in Python: the vertex block and a
uniform face block (every face of the same size) by its table parser, a mixed
face block by the vectorised token layout of :mod:`._textparse`.
"""

from __future__ import annotations

import io as _stdio
import re
import warnings
from pathlib import Path

import numpy as np

from ._common import (
    _COLOUR_NAMES,
    _NORMAL_NAMES,
    PointCloud,
    _cloud_from_columns,
    _colours_to_uint8,
    _is_integral,
    _quoted,
    _read_error,
)
from ._textparse import (
    SEPARATORS,
    _decode_text,
    _first_bad_line,
    _first_byte_outside,
    _iter_lines,
    _strip_comment,
    _token_layout,
    _whole_numbers,
)


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
    faces = _check_obj_faces(path, text, table.shape[0])
    return _cloud_from_columns(
        columns, path, fmt, text_colours=False, meta={"faces": faces} if faces else None
    )


# every whitespace byte as a space
_ALL_SPACES = bytes.maketrans(b"\t\n\v\f\r", b"     ")
# the bytes of a face corner: the vertex index, then an optional texture and normal index ("i", "i/t", "i//n",
# "i/t/n")
_CORNER_BYTES = b"0123456789+-/"


def _uniform_obj_corners(body: bytes, n_faces: int):
    """The vertex indices of OBJ faces of one size whose corners all have one form, or None.

    The common case (all triangles, every corner ``i//n``, say), checked with a few passes of
    :meth:`bytes.translate` and friends and parsed by NumPy's table parser: every corner then
    has the same number of slashes, none at the edge of a corner, and its indices are whole
    numbers. Returns an array of shape (faces, corners), or None for anything else, which
    :func:`_obj_corners` examines corner by corner.
    """
    single = body.replace(b"//", b"/")  # i//n as i/n: the vertex index comes first either way
    spaced = single.translate(_ALL_SPACES)
    if (b"//" in single or b"/ " in spaced or b" /" in spaced or spaced.startswith(b"/")
            or spaced.endswith(b"/")):
        return None  # "///", or a corner with an empty index
    outline = b" " + spaced.translate(None, b"0123456789+-") + b" "  # each corner's slashes, alone
    n_slashes = outline.count(b"/")
    first = outline.find(b"/")
    per_corner = outline.find(b" ", first) - first if n_slashes else 0  # the first corner's slashes
    if per_corner == 1 and b"//" in outline:
        return None
    if per_corner == 2 and (b"///" in outline or b" / " in outline):
        return None
    if per_corner > 2:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # older NumPy parses "1.5" as an int with a warning
            table = np.loadtxt(_stdio.BytesIO(single.replace(b"/", b" ")), dtype=np.int64, comments=None, ndmin=2)
    except (ValueError, Warning, OverflowError):
        return None
    step = per_corner + 1  # numbers per corner
    if table.shape[0] != n_faces or table.shape[1] % step:
        return None
    # every corner with slashes has exactly per_corner of them; those without must not exist
    corners = table.size // step
    if n_slashes and outline.count(b"/" * per_corner) != corners:
        return None
    doubles = body.count(b"//")
    if doubles and (doubles != corners or per_corner != 1):  # i//n: one "//" in every corner and no other slash
        return None
    return table[:, ::step]


def _obj_corners(path: Path, text: str, body: bytes, n_faces: int) -> tuple:
    """The vertex index of every corner of OBJ faces, and its face: each corner located and checked.

    Parameters
    ----------
    path : Path
        The file (for messages).
    text : str
        The whole file (to find a face's line in a message).
    body : bytes
        The ``f`` lines without their keyword and comments, one face per line.
    n_faces : int
        The number of ``f`` lines.

    Returns
    -------
    values, faces : ndarray of int64
        The vertex index of each corner as written (1-based, or negative), and its face.
    """
    starts, ends, first, sizes, lines = _token_layout(body)  # one face per line of ``body``
    if len(lines) < n_faces:
        empty = int(np.flatnonzero(np.append(lines, n_faces) != np.arange(len(lines) + 1))[0])
        raise _read_error(path, f"line {_obj_line_number(text, empty, 'f')}: a face ('f') with no vertices")
    faces = np.repeat(np.arange(n_faces), sizes)  # the face of each corner
    raw = np.frombuffer(body, dtype=np.uint8)
    bad = _first_byte_outside(body, _CORNER_BYTES + SEPARATORS)
    slashes = np.append(np.flatnonzero(raw == ord("/")), len(raw))  # a last one past the end: never inside a corner
    first_slash = np.searchsorted(slashes, starts)
    n_slashes = np.searchsorted(slashes, ends) - first_slash
    vertex_end = np.minimum(slashes[first_slash], ends)
    values, whole = _whole_numbers(body, starts, vertex_end)
    wrong = ~whole | (n_slashes > 2)
    if bad >= 0:
        wrong[int(np.searchsorted(starts, bad, side="right")) - 1] = True
    wrong = np.flatnonzero(wrong)
    if wrong.size:
        k = int(wrong[0])
        corner = body[starts[k] : ends[k]].decode(errors="replace")
        raise _read_error(
            path,
            f"line {_obj_line_number(text, int(faces[k]), 'f')}: {_quoted(corner)} is not a face corner "
            "(a vertex index, then optionally '/' texture index and '/' normal index)",
        )
    return values, faces


def _check_obj_faces(path: Path, text: str, n_vertices: int) -> int:
    """Check the ``f`` lines of an OBJ file: each corner's vertex index names a vertex; returns their number.

    Positive indices count from 1 at the first ``v`` line; negative ones from the last ``v`` line
    before the face (-1). Texture and normal indices are not checked against ``vt`` and ``vn``.
    """
    face_lines = re.findall(r"(?m)^[ \t]*f[ \t]+([^\n]*)$", text)
    if not face_lines:
        return 0
    body = "\n".join(face_lines)
    if "#" in body:
        body = re.sub(r"#[^\n]*", "", body)
    body = body.encode()
    uniform = _uniform_obj_corners(body, len(face_lines))
    if uniform is not None:
        values = uniform.ravel()
        faces = np.repeat(np.arange(len(face_lines)), uniform.shape[1])  # the face of each corner
    else:
        values, faces = _obj_corners(path, text, body, len(face_lines))
    if np.any(values < 0):  # relative: the vertices defined before the face line
        kinds = np.array(re.findall(r"(?m)^[ \t]*([vf])[ \t]", text))
        is_vertex = kinds == "v"
        defined = np.cumsum(is_vertex)[~is_vertex][faces]
        resolved = np.where(values < 0, defined + values, values - 1)
    else:
        defined = None
        resolved = values - 1
    wrong = np.flatnonzero((values == 0) | (resolved < 0) | (resolved >= n_vertices))
    if wrong.size:
        k = int(wrong[0])
        if values[k] == 0:
            problem = "vertex index 0 (OBJ indices start at 1, or count back from -1)"
        elif values[k] < 0:
            problem = f"the face follows {_count(defined[k], 'v line', 'v lines')}"
        else:
            problem = f"the file has {_count(n_vertices, 'v line', 'v lines')}"
        if values[k] != 0:
            problem = f"vertex index {values[k]} is out of range: {problem}"
        raise _read_error(path, f"line {_obj_line_number(text, int(faces[k]), 'f')}: {problem}")
    return len(face_lines)


def _obj_line_number(text: str, index: int, keyword: str = "v") -> int:
    """Line number in the file of the ``index``-th (0-based) ``keyword`` line (error path only)."""
    for found, match in enumerate(re.finditer(rf"(?m)^[ \t]*{keyword}[ \t]+", text)):
        if found == index:
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


def _count(number, singular: str, plural: str) -> str:
    """``'1 vertex'``, ``'2 vertices'``: a count and its noun."""
    return f"{number} {singular if number == 1 else plural}"


def _line_start(text: str, number: int) -> int:
    """Offset in ``text`` of the start of line ``number`` (1-based; ``len(text)`` past the end)."""
    start = 0
    for _ in range(number - 1):
        end = text.find("\n", start)
        if end < 0:
            return len(text)
        start = end + 1
    return start


def _line_text(text: str, number: int) -> str:
    """Line ``number`` (1-based) of ``text``, stripped (error messages only)."""
    start = _line_start(text, number)
    end = text.find("\n", start)
    return text[start : len(text) if end < 0 else end].strip()


# a comment runs to the end of its line: removed with the spaces before it, the line itself stays
# (line numbers unchanged; a line that held only a comment is then empty, like a blank one)
_OFF_COMMENT = re.compile(r"[ \t\f\v]*(?:#|//)[^\n]*")
# the values after a face's vertex indices: none, a colour-map index, RGB or RGBA
_OFF_FACE_COLOUR_SIZES = (0, 1, 3, 4)


def _read_off(path: Path, fmt: str) -> PointCloud:
    text = _decode_text(path)
    keyword, match, counts_line, n_vertices, n_faces = _off_header(path, _iter_lines(text))
    body = _OffBody(text, counts_line)
    available = len(body.filled)
    if n_vertices > available:
        raise _read_error(
            path,
            f"truncated: the header announces {_count(n_vertices, 'vertex', 'vertices')}, the file has "
            f"{available} line{'' if available == 1 else 's'} after line {counts_line}",
        )
    ncols = len(body.block(0, 1).split())
    has_texture, has_colour, has_normal = (bool(match.group(k)) for k in (1, 2, 3))
    n_colour = ncols - 3 - 3 * has_normal - 2 * has_texture
    if (has_colour and n_colour not in (3, 4)) or (not has_colour and n_colour != 0):
        raise _read_error(path, f"line {body.line_number(0)}: {ncols} values do not match a {keyword} vertex")
    table = _off_vertices(path, body, n_vertices, ncols)
    if n_faces > available - n_vertices:
        left = available - n_vertices
        raise _read_error(
            path,
            f"the header announces {n_faces} face{'' if n_faces == 1 else 's'}, the file has "
            f"{_count(left, 'line', 'lines')} after its {_count(n_vertices, 'vertex', 'vertices')}",
        )
    if n_faces:
        _check_off_faces(path, text, body.block(n_vertices, n_faces), n_vertices, n_faces,
                         body.line_number(n_vertices))
    if available > n_vertices + n_faces:
        raise _read_error(
            path,
            f"line {body.line_number(n_vertices + n_faces)}: more lines than the header announces "
            f"({_count(n_vertices, 'vertex', 'vertices')} and {_count(n_faces, 'face', 'faces')})",
        )
    names = ["x", "y", "z"] + (list(_NORMAL_NAMES) if has_normal else [])
    columns = {name: np.ascontiguousarray(table[:, k]) for k, name in enumerate(names)}
    cloud = _cloud_from_columns(
        columns, path, fmt, text_colours=False, meta={"faces": n_faces} if n_faces else None
    )
    if has_colour:
        _add_off_colours(path, cloud, table[:, len(names) : len(names) + n_colour])
    if has_texture:
        cloud.fields["s"] = np.ascontiguousarray(table[:, ncols - 2])
        cloud.fields["t"] = np.ascontiguousarray(table[:, ncols - 1])
    return cloud


def _off_header(path: Path, lines) -> tuple:
    """``(keyword, match, counts_line, n_vertices, n_faces)`` of an OFF file's header.

    ``match`` is the keyword's match of the variants (``ST``, ``C``, ``N``, ``4``, ``n`` groups);
    ``counts_line`` the line number of the counts. The third count, of edges, is ignored: real files
    often give 0 or a wrong number.
    """
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
    return keyword, match, counts_line, n_vertices, _off_count(path, tokens, 1, "face", counts_line)


class _OffBody:
    """The lines after an OFF file's counts, comments removed: every line not blank holds one vertex, then one face.

    ``filled`` holds the indices of the lines that are not blank, among all the body's lines.
    """

    def __init__(self, text: str, counts_line: int):
        self.counts_line = counts_line
        body = text[_line_start(text, counts_line + 1) :]
        if "#" in body or "//" in body:
            body = _OFF_COMMENT.sub("", body)
        self.body = body.encode()
        raw = np.frombuffer(self.body, dtype=np.uint8)
        self.line_ends = np.append(np.flatnonzero(raw == 10), len(raw))
        self.line_starts = np.append(0, self.line_ends[:-1] + 1)
        # blank lines are empty (_decode_text), comments removed
        self.filled = np.flatnonzero(self.line_ends > self.line_starts)

    def block(self, first: int, count: int) -> bytes:
        """The lines of the ``count`` vertices or faces from the ``first``-th (blank lines among them)."""
        return self.body[self.line_starts[self.filled[first]] : self.line_ends[self.filled[first + count - 1]]]

    def line_number(self, index: int) -> int:
        """The line number in the file of the ``index``-th vertex or face."""
        return self.counts_line + 1 + int(self.filled[index])


def _off_vertices(path: Path, body: _OffBody, n_vertices: int, ncols: int) -> np.ndarray:
    """The vertex lines as a table, shape (n_vertices, ncols); an error names the first line that is not one."""
    vertices = body.block(0, n_vertices).decode()
    try:
        table = np.loadtxt(_stdio.StringIO(vertices), dtype=np.float64, comments=None, ndmin=2)
        if table.shape != (n_vertices, ncols):
            raise ValueError("a line of another length")
    except ValueError:
        bad = _first_bad_line(vertices, 0, ncols, None)
        if bad is None:
            raise _read_error(path, f"cannot parse the {n_vertices} vertices") from None
        body_line = int(body.filled[0]) + bad[0] - 1
        index = int(np.searchsorted(body.filled, body_line))
        raise _read_error(
            path,
            f"line {body.counts_line + 1 + body_line}: {bad[1]} (vertex {index + 1} of the {n_vertices} "
            "the header announces)",
        ) from None
    return table


def _add_off_colours(path: Path, cloud: PointCloud, rgba: np.ndarray) -> None:
    """Set ``cloud``'s colours from an OFF file's vertex colours ``rgba``, shape (n, 3) or (n, 4)."""
    # Geomview colours are floats 0-1, MeshLab writes integers 0-255 (alpha included)
    as_bytes = _is_integral(rgba) and rgba.max(initial=0) > 1
    cloud.colours = _colours_to_uint8(rgba[:, :3], text=as_bytes)
    if cloud.colours is None:
        raise _read_error(path, "vertex colours are neither 0-255 integers nor 0-1 fractions")
    if not np.array_equal(cloud.colours, rgba[:, :3]):
        cloud.meta["colour_values"] = np.ascontiguousarray(rgba[:, :3])  # 0-1 fractions
    if rgba.shape[1] == 4:
        cloud.fields["alpha"] = np.ascontiguousarray(rgba[:, 3])


def _uniform_faces_in_range(faces: bytes, n_vertices: int, n_faces: int) -> bool:
    """Whether every face line is ``k i1 .. ik`` with the same ``k`` and the same colour size, indices in range.

    The common case (all triangles, all quads, one colour for every face), parsed by NumPy's
    table parser; False for anything else, which :func:`_check_off_faces` then examines token
    by token.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # older NumPy parses "1.5" as an int with a warning
            table = np.loadtxt(_stdio.StringIO(faces.decode()), dtype=np.int64, comments=None, ndmin=2)
    except (ValueError, Warning, UnicodeDecodeError, OverflowError):
        return False
    if table.shape[0] != n_faces or table.shape[1] < 2:
        return False
    corners = int(table[0, 0])
    if not np.all(table[:, 0] == corners) or not 1 <= corners <= table.shape[1] - 1:
        return False
    if table.shape[1] - 1 - corners not in _OFF_FACE_COLOUR_SIZES:
        return False
    indices = table[:, 1 : 1 + corners]
    return bool(indices.min() >= 0 and indices.max() < n_vertices)


def _check_off_faces(path, text, faces, n_vertices, n_faces, first_line) -> None:
    """Check the face lines of an OFF file: ``k i1 .. ik`` and an optional colour, indices in range.

    Parameters
    ----------
    path : Path
        The file (for messages).
    text : str
        The whole file (to quote a line in a message).
    faces : bytes
        The face lines, comments removed (blank lines may be among them).
    n_vertices, n_faces : int
        The header's counts: ``faces`` holds ``n_faces`` lines that are not blank.
    first_line : int
        The line number in the file of the first face.
    """
    if _uniform_faces_in_range(faces, n_vertices, n_faces):
        return
    # a mixed or a broken face block: every face and token located, to name the first problem
    starts, ends, first, sizes, numbers = _token_layout(faces)
    numbers += first_line  # the line number in the file of each face
    body = faces
    corners, whole = _whole_numbers(body, starts[first], ends[first])
    bad = np.flatnonzero(~whole)
    if bad.size:
        number = int(numbers[bad[0]])
        raise _read_error(
            path,
            f"line {number}: expected a face ('k i1 ... ik') after the {_count(n_vertices, 'vertex', 'vertices')} "
            f"the header announces, found {_quoted(_line_text(text, number))}",
        )
    bad = np.flatnonzero((corners < 1) | (corners > sizes - 1))
    if bad.size:
        k = int(bad[0])
        problem = (f"a face of {_count(corners[k], 'vertex', 'vertices')}" if corners[k] < 1 else
                   f"the face announces {_count(corners[k], 'vertex', 'vertices')}, the line holds "
                   f"{_count(sizes[k] - 1, 'value', 'values')} after it")
        raise _read_error(path, f"line {numbers[k]}: {problem}")
    extra = sizes - 1 - corners
    bad = np.flatnonzero(~np.isin(extra, _OFF_FACE_COLOUR_SIZES))
    if bad.size:
        k = int(bad[0])
        raise _read_error(
            path,
            f"line {numbers[k]}: {extra[k]} values after the face's {corners[k]} vertex indices "
            "(a face colour is 1, 3 or 4 values)",
        )
    # the index tokens: the corners[k] tokens after the first token of face k
    owner = np.repeat(np.arange(len(first)), corners)
    position = np.repeat(first + 1, corners) + np.arange(len(owner)) - np.repeat(np.cumsum(corners) - corners, corners)
    indices, whole = _whole_numbers(body, starts[position], ends[position])
    bad = np.flatnonzero(~whole)
    if bad.size:
        k = int(bad[0])
        token = body[starts[position[k]] : ends[position[k]]].decode(errors="replace")
        raise _read_error(path, f"line {numbers[owner[k]]}: face vertex index {_quoted(token)} is not a whole number")
    bad = np.flatnonzero((indices < 0) | (indices >= n_vertices))
    if bad.size:
        k = int(bad[0])
        raise _read_error(
            path,
            f"line {numbers[owner[k]]}: face vertex index {indices[k]} is out of range "
            f"(the header announces {_count(n_vertices, 'vertex', 'vertices')}, numbered 0 to {n_vertices - 1})",
        )
    if np.any(extra):  # the colours are not read, but must be numbers
        bad = _first_byte_outside(body[: ends[first[-1] + sizes[-1] - 1]], b"0123456789+-.eE" + SEPARATORS)
        if bad >= 0:
            token = int(np.searchsorted(starts, bad, side="right")) - 1
            face = int(np.searchsorted(first, token, side="right")) - 1
            value = body[starts[token] : ends[token]].decode(errors="replace")
            raise _read_error(path, f"line {numbers[face]}: face colour value {_quoted(value)} is not a number")
