"""Line-oriented text parsing shared by the text-table reader and the OBJ/OFF readers.

Decoding, comments, delimiters, and numpy's fast table parser with a slow
second pass that names the first bad line when numpy fails.
"""

from __future__ import annotations

import io as _stdio
import re
from pathlib import Path

import numpy as np

from ._common import _one_line, _quoted, _read_error


def _decode_text(path: Path) -> str:
    """The file as text with ``\\n`` line ends (UTF-8, else Latin-1; UTF-16 with a byte-order mark).

    Lines holding only spaces and tabs are emptied (a blank line, wherever it is).
    """
    raw = path.read_bytes()
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            text = raw.decode("utf-16")
        except UnicodeDecodeError as exc:
            raise _read_error(
                path, f"the file starts with a UTF-16 byte-order mark but is not UTF-16 text (byte {exc.start})"
            ) from None
        if "\x00" in text:
            raise _read_error(path, "binary data, not a text file (a NUL character)")
    elif b"\x00" in raw:
        head = raw[:65536]
        if len(head) >= 4 and (head[1::2].count(0) > len(head) // 4 or head[0::2].count(0) > len(head) // 4):
            raise _read_error(
                path, "binary data, not a text file (UTF-16 without a byte-order mark? save it as UTF-8)"
            )
        raise _read_error(path, "binary data, not a text file")
    else:
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError:
            text = raw.decode("latin-1")
    del raw
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    return _empty_blank_lines(text)


# spaces and tabs alone on a line after the first (numpy's parser with a delimiter reads
# them as a row); a pattern starting with a literal is searched fast, unlike ``^...$``
_BLANK = re.compile(r"\n[ \t\f\v]+(?=\n)")
_SPACE = " \t\f\v"


def _empty_blank_lines(text: str) -> str:
    """``text`` with every line of spaces and tabs only emptied (line numbers unchanged)."""
    if _BLANK.search(text):
        text = _BLANK.sub("\n", text)
    first = text.find("\n")
    if first > 0 and not text[:first].strip(_SPACE):
        text = text[first:]
    last = text.rfind("\n") + 1
    if last < len(text) and not text[last:].strip(_SPACE):
        text = text[:last]
    return text


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
                shown = _quoted(token) if token else "an empty value"  # the message stays one short line
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


#: The bytes that separate tokens: ASCII whitespace, as :meth:`bytes.split` sees it.
SEPARATORS = b" \t\n\v\f\r"


def _first_byte_outside(data: bytes, allowed: bytes) -> int:
    """Offset of the first byte of ``data`` that is not one of ``allowed``, or -1 (one pass, in C)."""
    rest = data.translate(None, allowed)
    return data.find(rest[:1]) if rest else -1


def _token_layout(data: bytes) -> tuple:
    """Where the whitespace-separated tokens of ``data`` are, and which lines hold them (vectorised).

    Parameters
    ----------
    data : bytes
        Text with ``\\n`` line ends, comments already removed.

    Returns
    -------
    starts, ends : ndarray of int64
        Offset of each token's first byte and one past its last.
    first : ndarray of int64
        Per line that holds a token: the index of its first token.
    sizes : ndarray of int64
        Per line that holds a token: its number of tokens.
    lines : ndarray of int64
        Per line that holds a token: its 0-based line number in ``data``.
    """
    raw = np.frombuffer(data, dtype=np.uint8)
    separator = (raw - np.uint8(9) <= 4) | (raw == ord(" "))  # SEPARATORS: 9-13 and 32
    mark = ~separator
    mark[1:] &= separator[:-1]
    starts = np.flatnonzero(mark)
    mark = ~separator
    mark[:-1] &= separator[1:]
    ends = np.flatnonzero(mark) + 1
    del mark, separator
    newlines = np.flatnonzero(raw == 10)
    # a token opens a line when a line end lies between it and the token before it
    opens = np.zeros(len(starts) + 1, dtype=bool)
    opens[np.searchsorted(starts, newlines)] = True
    opens[0] = True
    first = np.flatnonzero(opens[: len(starts)])
    lines = np.searchsorted(newlines, starts[first])
    return starts, ends, first, np.diff(first, append=len(starts)), lines


def _whole_numbers(data: bytes, starts: np.ndarray, ends: np.ndarray, chunk: int = 1 << 20) -> tuple:
    """The tokens of ``data`` between ``starts`` and ``ends`` read as integers (vectorised).

    A whole number is an optional sign and 1 to 18 decimal digits. The digits of
    ``chunk`` tokens at a time are laid out right-aligned in a matrix and
    multiplied by the powers of ten.

    Returns
    -------
    values : ndarray of int64
        The value of each token; 0 where it is not a whole number.
    whole : ndarray of bool
        Which tokens are whole numbers.
    """
    raw = np.frombuffer(data, dtype=np.uint8)
    starts = np.asarray(starts, dtype=np.int64)
    ends = np.asarray(ends, dtype=np.int64)
    values = np.zeros(starts.shape, dtype=np.int64)
    whole = np.zeros(starts.shape, dtype=bool)
    if not starts.size:
        return values, whole
    first = raw[starts]
    negative = first == ord("-")
    n_digits = ends - starts - (negative | (first == ord("+")))
    for at in range(0, len(starts), chunk):
        part = slice(at, at + chunk)
        count = n_digits[part]
        width = int(np.clip(count.max(), 1, 18))
        place = np.arange(width)
        used = place >= width - count[:, None]
        digits = raw[np.maximum(ends[part, None] - width + place, 0)] - np.uint8(ord("0"))  # wraps below '0'
        whole[part] = (count >= 1) & (count <= 18) & ~np.any(used & (digits > 9), axis=1)
        values[part] = np.where(used, digits, 0).astype(np.int64) @ (10 ** np.arange(width - 1, -1, -1))
    values[~whole] = 0
    return np.where(negative, -values, values), whole
