"""Line-oriented text parsing shared by the text-table reader and the OBJ/OFF readers.

Decoding, comments, delimiters, and numpy's fast table parser with a slow
second pass that names the first bad line when numpy fails.
"""

from __future__ import annotations

import io as _stdio
from pathlib import Path

import numpy as np

from ._common import _one_line, _read_error


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
