"""Text tables: XYZ, TXT, CSV and PTS reading (header and delimiter detected) and writing."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._common import (
    _COLOUR_NAMES,
    _NORMAL_NAMES,
    _ROLE_OF,
    PointCloud,
    _canonical,
    _cloud_from_columns,
    _is_integral,
    _ordered_columns,
    _Output,
    _read_error,
)
from ._textparse import _decode_text, _guess_delimiter, _is_number, _iter_lines, _load_table, _split, _strip_comment

# rows formatted per call when writing text
_TEXT_BLOCK = 65536


def _looks_like_rgb(block: np.ndarray) -> bool:
    """Columns (n, 3) of integers 0-255 that are not all unit vectors (normals)."""
    if block.size == 0 or not _is_integral(block) or block.min() < 0 or block.max() > 255:
        return False
    unit = np.abs(np.linalg.norm(block, axis=1) - 1.0) < 1e-3
    return not bool(np.all(unit))


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
    """Column names of a header-less text table (see the notes of :mod:`heatcurv.io`)."""
    ncols = table.shape[1]
    extra = [f"column_{k}" for k in range(4, ncols + 1)]
    names = ["x", "y", "z"] + extra
    if ncols == 4 and ext == ".pts":
        names = ["x", "y", "z", "intensity"]
    elif ncols == 6:
        names = ["x", "y", "z"] + (
            list(_COLOUR_NAMES) if _looks_like_rgb(table[:, 3:6]) else list(_NORMAL_NAMES)
        )
    elif ncols == 7 and _looks_like_rgb(table[:, 4:7]):
        names = ["x", "y", "z", "intensity", *_COLOUR_NAMES]
    elif ncols == 9:
        if _looks_like_rgb(table[:, 3:6]) and not _looks_like_rgb(table[:, 6:9]):
            names = ["x", "y", "z", *_COLOUR_NAMES, *_NORMAL_NAMES]
        elif _looks_like_rgb(table[:, 6:9]):
            names = ["x", "y", "z", *_NORMAL_NAMES, *_COLOUR_NAMES]
    elif ncols == 10 and _looks_like_rgb(table[:, 4:7]):
        names = ["x", "y", "z", "intensity", *_COLOUR_NAMES, *_NORMAL_NAMES]
    return names


# a PTS count line: an integer alone on its line
_PTS_COUNT = re.compile(r"^[ \t]*(\d+)[ \t]*$", re.MULTILINE)
# no file holds 10**18 points; longer counts are not converted (Python refuses beyond 4300 digits)
_MAX_COUNT_DIGITS = 18


def _pts_counts(text: str) -> list:
    """``(line_number, count)`` of every PTS count line; a count of more than 18 digits is ``10**18``."""
    counts, line, last = [], 1, 0
    for match in _PTS_COUNT.finditer(text):
        line += text.count("\n", last, match.start())
        last = match.start()
        digits = match.group(1)
        counts.append((line, int(digits) if len(digits) <= _MAX_COUNT_DIGITS else 10**_MAX_COUNT_DIGITS))
    return counts


def _check_pts_counts(path: Path, text: str, counts: list, data_line: int, rows: int) -> None:
    """Refuse a PTS file whose count lines do not match the rows that follow each of them.

    ``text`` has its count lines emptied; ``rows`` is the number of rows read from
    ``data_line`` on. Rows before the first count line belong to no count.
    """
    if counts[0][0] < data_line and sum(count for _, count in counts) == rows:
        return
    starts = [line for line, _ in counts]
    found = [0] * len(counts)
    scan = -1
    for number, line in _iter_lines(text):  # a mismatch: count the rows of each scan
        while scan + 1 < len(starts) and number >= starts[scan + 1]:
            scan += 1
        if scan >= 0 and number >= data_line and _strip_comment(line):
            found[scan] += 1
    for (line, said), got in zip(counts, found):
        if said != got:
            points = "point" if said == 1 else "points"
            said_text = str(said) if said < 10**_MAX_COUNT_DIGITS else f"more than 10**{_MAX_COUNT_DIGITS}"
            raise _read_error(path, f"line {line}: the count line says {said_text} {points}, {got} follow")


def _read_text(path: Path, fmt: str) -> PointCloud:
    ext = "." + fmt
    text = _decode_text(path)
    counts = []
    if ext == ".pts":
        # Leica PTS: each scan starts with a line holding its point count.
        counts = _pts_counts(text)
        text = _PTS_COUNT.sub("", text)

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
    if counts:
        _check_pts_counts(path, text, counts, data_line, table.shape[0])
    names = _unique_names(names) if names is not None else _positional_names(table, ext)
    columns = {name: np.ascontiguousarray(table[:, k]) for k, name in enumerate(names)}
    return _cloud_from_columns(columns, path, fmt, text_colours=True)


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
