"""Mutators of the fuzz campaign (:mod:`support.fuzz`): pure functions that break a file's bytes.

Each :class:`Mutator` is a named pure function ``(bytes, numpy.random.Generator)
-> bytes`` with the format families it applies to; :data:`MUTATORS` holds them
all in registration order:

==========================  ====================================================
generic (every format)      ``truncate-random``, ``truncate-boundary`` (at a
                            header end, a line end, a zip or LAS record),
                            ``flip-bits``, ``header-bytes``, ``random-run``,
                            ``special-run``, ``delete-run``, ``insert-random``,
                            ``append-garbage``, ``duplicate-block``
text (the ascii PLY too)    ``utf16``, ``bom``, ``latin1``, ``line-endings``
                            (CRLF, CR, ...), ``nul``, ``token-value`` (nan,
                            1e309, 5000 digits, unicode digits, ...),
                            ``token-count``, ``line-shuffle``, ``long-line``
PLY                         ``ply-count`` (element counts), ``ply-type``
                            (property types swapped), ``ply-format``,
                            ``ply-header-lines``
OFF, OBJ, PTS               ``off-counts``, ``off-lines`` (vertex and face
                            lines duplicated, deleted, indices out of range,
                            ...), ``obj-faces``, ``off-keyword``, ``pts-count``
NPY                         ``npy-header`` (shape, dtype, fortran_order, stale
                            header length), ``npy-version``
NPZ                         ``npz-bomb`` (zip bombs: 256 MiB of zeros, a
                            2**40-row header, one member listed 64 times,
                            20000 members, 4 GiB sizes), ``npz-member``
                            (non-array members), ``npz-member-npy``,
                            ``zip-fields``
LAS, LAZ                    ``las-point-count``, ``las-vlr-count``,
                            ``las-point-offset``, ``las-record-length``,
                            ``las-scale`` (0, NaN, inf, 1e-300, ...),
                            ``las-offset-bbox`` (offsets, a box too small,
                            NaN), ``las-format`` (point format, version,
                            header size), ``las-vlr``, ``las-point-format``
                            (another format, same record length),
                            ``las-misalign`` (bytes inserted in the points,
                            VLR bytes duplicated, records shifted)
LAZ                         ``laz-chunk-table`` (offset, chunk count, version),
                            ``laz-vlr`` (the laszip record's fields, item types)
==========================  ====================================================
"""

from __future__ import annotations

import ast
import io
import re
import struct
import warnings
import zipfile
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["MUTATORS", "Mutator", "N_SEED", "header_end", "mutate", "npy_header"]

#: Points in every seed file (some counts written into headers are this one plus or minus one).
N_SEED = 120


@dataclass(frozen=True)
class Mutator:
    """A named pure function ``(bytes, numpy.random.Generator) -> bytes`` and the variants it applies to.

    Attributes
    ----------
    name : str
    function : callable
    families : tuple of str or None
        Format families (:attr:`support.fuzz.Variant.family`) it applies to; None: all.
    textual : bool or None
        True: text variants only; False: binary only; None: both.
    """

    name: str
    function: object
    families: tuple | None = None
    textual: bool | None = None

    def __call__(self, data: bytes, rng) -> bytes:
        return self.function(data, rng)

    def applies(self, family: str, textual: bool) -> bool:
        """Whether it applies to a file of format ``family``, text or binary."""
        return (self.families is None or family in self.families) and (
            self.textual is None or self.textual == textual)


#: Every mutator, by name (registration order).
MUTATORS: dict = {}


def _mutator(name, families=None, textual=None):
    def register(function):
        MUTATORS[name] = Mutator(name, function, families, textual)
        return function
    return register


def _pick(rng, values):
    return values[int(rng.integers(len(values)))]


def _position(rng, data: bytes, end=None) -> int:
    return int(rng.integers(max(1, len(data) if end is None else min(end, len(data)))))


_INTERESTING = [0, 1, 2, 119, 121, 255, 256, 65535, 65536, 2**31 - 1, 2**31, 2**32 - 1, 2**32, 2**53,
                2**63 - 1, 2**64 - 1]


def header_end(data: bytes) -> int:
    """Where the structured header of a file ends (PLY end_header, LAS/NPY header size), else 512."""
    if data.startswith(b"ply"):
        end = data.find(b"end_header")
        return len(data) if end < 0 else data.find(b"\n", end) + 1 or len(data)
    if data.startswith(b"LASF") and len(data) >= 100:
        return struct.unpack_from("<I", data, 96)[0]
    if data.startswith(b"\x93NUMPY") and len(data) >= 10:
        return 10 + struct.unpack_from("<H", data, 8)[0]
    return min(512, len(data))


def _boundaries(data: bytes) -> list:
    """Offsets where a file's structure changes: header ends, line ends, zip records, LAS records."""
    found = {header_end(data)}
    found.update(m.end() for m in re.finditer(rb"\n", data[:65536]))
    found.update(m.start() for m in re.finditer(rb"PK\x03\x04|PK\x01\x02|PK\x05\x06|PK\x06\x06", data))
    if data.startswith(b"LASF") and len(data) >= 107:
        header_size, offset, vlrs = struct.unpack_from("<HII", data, 94)
        record = struct.unpack_from("<H", data, 105)[0]
        found.update({header_size, header_size + 54, offset, offset + 8, offset + record, len(data) - record})
        found.update(offset + k * record for k in (1, 2, N_SEED // 2, N_SEED - 1))
    return sorted(b for b in found if 0 < b < len(data)) or [len(data) // 2]


@_mutator("truncate-random")
def _truncate_random(data, rng):
    return data[: _position(rng, data)]


@_mutator("truncate-boundary")
def _truncate_boundary(data, rng):
    cut = _pick(rng, _boundaries(data)) + int(rng.integers(-1, 2))
    return data[: max(0, cut)]


@_mutator("flip-bits")
def _flip_bits(data, rng):
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 9))):
        at = _position(rng, out)
        out[at] ^= 1 << int(rng.integers(8))
    return bytes(out)


@_mutator("header-bytes")
def _header_bytes(data, rng):
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 5))):
        out[_position(rng, out, header_end(data))] = int(rng.integers(256))
    return bytes(out)


@_mutator("random-run")
def _random_run(data, rng):
    at, length = _position(rng, data), int(rng.integers(1, 257))
    return data[:at] + rng.bytes(length) + data[at + length:]


@_mutator("special-run")
def _special_run(data, rng):
    at, length = _position(rng, data), int(rng.integers(1, 65))
    return data[:at] + bytes([_pick(rng, [0x00, 0xFF, 0x7F, 0x80, 0x20, 0x0A, 0x2D])]) * length + data[at + length:]


@_mutator("delete-run")
def _delete_run(data, rng):
    at = _position(rng, data)
    return data[:at] + data[at + int(rng.integers(1, 513)):]


@_mutator("insert-random")
def _insert_random(data, rng):
    at = _position(rng, data)
    return data[:at] + rng.bytes(int(rng.integers(1, 65))) + data[at:]


@_mutator("append-garbage")
def _append_garbage(data, rng):
    kind = int(rng.integers(4))
    tail = [rng.bytes(int(rng.integers(1, 4097))), data, b"\x00" * int(rng.integers(1, 65537)),
            b"\n" * int(rng.integers(1, 100001))][kind]
    return data + tail


@_mutator("duplicate-block")
def _duplicate_block(data, rng):
    start = _position(rng, data)
    block = data[start: start + int(rng.integers(1, 2049))]
    at = _position(rng, data)
    return data[:at] + block * int(rng.integers(1, 4)) + data[at:]


# --- encodings (text variants, the ascii PLY included)
@_mutator("utf16", textual=True)
def _utf16(data, rng):
    return data.decode("latin-1").encode(_pick(rng, ["utf-16", "utf-16-le", "utf-16-be", "utf-32"]))


@_mutator("bom", textual=True)
def _bom(data, rng):
    return _pick(rng, [b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff", b"\xef\xbb\xbf\xef\xbb\xbf"]) + data


@_mutator("latin1", textual=True)
def _latin1(data, rng):
    text = _pick(rng, ["\u00b5m \u00e9t\u00e9 ", "\u00b0", "x\u00e9", "\u00a0"]).encode("latin-1")
    if rng.random() < 0.5:  # in the header / first lines, where names and counts are
        at = _position(rng, data, header_end(data))
    else:
        at = _position(rng, data)
    return data[:at] + text + data[at:]


@_mutator("line-endings", textual=True)
def _line_endings(data, rng):
    return data.replace(b"\n", _pick(rng, [b"\r\n", b"\r", b"\n\n", b"\r\r\n", b"\x0b", b"\x85"]))


@_mutator("nul", textual=True)
def _nul(data, rng):
    out = data
    for _ in range(int(rng.integers(1, 6))):
        at = _position(rng, out)
        out = out[:at] + b"\x00" * int(rng.integers(1, 4)) + out[at + int(rng.integers(0, 2)):]
    return out


_NUMBER = re.compile(rb"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")
_ODD_NUMBERS = [b"nan", b"NaN", b"inf", b"-inf", b"1e309", b"-1e309", b"1e-400", b"0x10", b"1_000", b"",
                b"--1", b"1e", b".", b"1.2.3", "\u0661\u0662".encode(), b"1,5", b"9" * 5000, b"+",
                "\u22121".encode(), "\uff11".encode(), b"true", b"1e999999999", b"-0", b"4294967296"]


@_mutator("token-value", textual=True)
def _token_value(data, rng):
    matches = list(_NUMBER.finditer(data[:200000]))
    if not matches:
        return data
    for _ in range(int(rng.integers(1, 4))):
        m = _pick(rng, matches)
        data = data[: m.start()] + _pick(rng, _ODD_NUMBERS) + data[m.end():]
        matches = list(_NUMBER.finditer(data[:200000])) or matches[:0]
        if not matches:
            break
    return data


@_mutator("token-count", textual=True)
def _token_count(data, rng):
    lines = data.split(b"\n")
    k = _pick(rng, [i for i in range(len(lines)) if lines[i].strip()] or [0])
    tokens = lines[k].split()
    if tokens and rng.random() < 0.5:
        del tokens[int(rng.integers(len(tokens)))]
    else:
        tokens.insert(int(rng.integers(len(tokens) + 1)), _pick(rng, [b"1", b"0.5", b"x", b"255", b"#"]))
    lines[k] = b" ".join(tokens)
    return b"\n".join(lines)


@_mutator("line-shuffle", textual=True)
def _line_shuffle(data, rng):
    lines = data.split(b"\n")
    head = min(len(lines), 12)
    i, j = int(rng.integers(head)), int(rng.integers(len(lines)))
    lines[i], lines[j] = lines[j], lines[i]
    return b"\n".join(lines)


@_mutator("long-line", textual=True)
def _long_line(data, rng):
    kind = int(rng.integers(3))
    line = [b"1 " * 200000, b"9" * 1000000, b"# " + b"x" * 1000000][kind] + b"\n"
    at = data.find(b"\n", _position(rng, data)) + 1
    return data[:at] + line + data[at:]


# --- PLY headers
def _ply_split(data):
    end = header_end(data)
    return data[:end], data[end:]


@_mutator("ply-count", families=("ply",))
def _ply_count(data, rng):
    head, body = _ply_split(data)
    element = _pick(rng, [b"vertex", b"vertex", b"face"] if b"element face" in head else [b"vertex"])
    value = _pick(rng, [str(v).encode() for v in _INTERESTING] + [b"-1", b"1e3", b"abc", b"", b"10" * 20])
    return re.sub(rb"(element " + element + rb" )\S*", lambda m: m.group(1) + value, head, count=1) + body


_PLY_TYPES = [b"char", b"uchar", b"short", b"ushort", b"int", b"uint", b"float", b"double", b"int8", b"uint8",
              b"int16", b"int32", b"uint32", b"float32", b"float64", b"float128", b"long", b"", b"list uchar int",
              b"list float float", b"list uint int", b"list char double"]


@_mutator("ply-type", families=("ply",))
def _ply_type(data, rng):
    head, body = _ply_split(data)
    props = list(re.finditer(rb"property (list \S+ \S+|\S+) ", head))
    if not props:
        return data
    m = _pick(rng, props)
    return head[: m.start(1)] + _pick(rng, _PLY_TYPES) + head[m.end(1):] + body


@_mutator("ply-format", families=("ply",))
def _ply_format(data, rng):
    head, body = _ply_split(data)
    line = _pick(rng, [b"ascii 1.0", b"binary_little_endian 1.0", b"binary_big_endian 1.0", b"binary 1.0",
                       b"ascii 2.0", b"ascii", b"", b"ascii 1.0 extra", b"ASCII 1.0"])
    return re.sub(rb"format [^\n]*", b"format " + line, head, count=1) + body


@_mutator("ply-header-lines", families=("ply",))
def _ply_header_lines(data, rng):
    head, body = _ply_split(data)
    lines = head.split(b"\n")
    k = int(rng.integers(1, max(2, len(lines) - 1)))
    edit = int(rng.integers(5))
    if edit == 0:
        del lines[k]
    elif edit == 1:
        lines.insert(k, lines[k])
    elif edit == 2:
        lines.insert(k, _pick(rng, [b"element vertex 5", b"property float x", b"element extra 1000000",
                                    b"obj_info \xff\xfe", b"comment \x00", b"end_header"]))
    elif edit == 3:
        lines[k] = lines[k].replace(b" x", b" y").replace(b" nx", b" ny")
    else:
        lines = [line for line in lines if line != b"end_header"]
    return b"\n".join(lines) + body


# --- OFF and PTS counts, OFF and OBJ faces
_OFF_COUNTS_LINE = re.compile(rb"\s*\d+\s+\d+\s+\d+\s*")


@_mutator("off-counts", families=("off",))
def _off_counts(data, rng):
    lines = data.split(b"\n")
    k = next((i for i, line in enumerate(lines) if _OFF_COUNTS_LINE.fullmatch(line)), None)
    if k is None:
        return data
    counts = lines[k].split()
    # one more or one fewer than the vertex and face lines (the seed's 120 and 118) among the values
    near = [str(v).encode() for v in (N_SEED - 3, N_SEED - 2, N_SEED - 1, N_SEED + 1)]
    choices = [str(v).encode() for v in _INTERESTING] + near + [b"-1", b"x", b"1.5", b"10" * 15]
    if rng.random() < 0.15:
        del lines[k]
    else:
        counts[int(rng.integers(3))] = _pick(rng, choices)
        lines[k] = b" ".join(counts)
    return b"\n".join(lines)


def _off_blocks(lines):
    """Index of the first vertex line of a seed OFF split in lines, and its vertex and face counts."""
    k = next(i for i, line in enumerate(lines) if _OFF_COUNTS_LINE.fullmatch(line))
    n_vertices, n_faces = (int(v) for v in lines[k].split()[:2])
    return k + 1, n_vertices, n_faces


def _off_face_tokens(lines, rng):
    """A random face line of a seed OFF: its index and its tokens."""
    start, n_vertices, n_faces = _off_blocks(lines)
    k = start + n_vertices + int(rng.integers(n_faces))
    return k, lines[k].split()


def _off_vertex_duplicated(lines, rng):
    start, n_vertices, _ = _off_blocks(lines)
    k = start + int(rng.integers(n_vertices))
    lines.insert(k, lines[k])


def _off_vertex_deleted(lines, rng):
    start, n_vertices, _ = _off_blocks(lines)
    del lines[start + int(rng.integers(n_vertices))]


def _off_face_duplicated(lines, rng):
    k, _ = _off_face_tokens(lines, rng)
    lines.insert(k, lines[k])


def _off_face_deleted(lines, rng):
    k, _ = _off_face_tokens(lines, rng)
    del lines[k]


def _off_index_out_of_range(lines, rng):
    k, tokens = _off_face_tokens(lines, rng)
    tokens[1 + int(rng.integers(int(tokens[0])))] = _pick(rng, [str(N_SEED).encode(), b"-1", b"4294967296"])
    lines[k] = b" ".join(tokens)


def _off_index_not_whole(lines, rng):
    k, tokens = _off_face_tokens(lines, rng)
    tokens[1 + int(rng.integers(int(tokens[0])))] = _pick(rng, [b"1.5", b"x", b"1e3", b"0x10", b"9" * 30])
    lines[k] = b" ".join(tokens)


def _off_corner_count(lines, rng):
    k, tokens = _off_face_tokens(lines, rng)
    tokens[0] = _pick(rng, [b"0", b"4", b"5", b"-3"])
    lines[k] = b" ".join(tokens)


def _off_face_values(lines, rng):
    k, tokens = _off_face_tokens(lines, rng)
    lines[k] = b" ".join(tokens + _pick(rng, [[b"7", b"7"], [b"1"] * 5, [b"red", b"0", b"0"]]))


def _off_line_appended(lines, rng):
    while lines and not lines[-1].strip():
        lines.pop()
    lines.append(_pick(rng, [b"0 0 0", b"3 0 1 2", b"1"]))
    lines.append(b"")


def _off_harmless(lines, rng):
    """Edits real files have, which every reader must accept: comments, blank lines, face colours."""
    start, n_vertices, n_faces = _off_blocks(lines)
    edit = int(rng.integers(4))
    if edit == 0:  # a comment line anywhere after the counts
        lines.insert(start + int(rng.integers(n_vertices + n_faces)), b"# a comment")
    elif edit == 1:  # blank lines and trailing spaces
        lines.insert(start + int(rng.integers(n_vertices + n_faces)), b"")
        lines.extend([b"   ", b"", b"\t"])
    elif edit == 2:  # an RGB colour on every face
        for k in range(start + n_vertices, start + n_vertices + n_faces):
            lines[k] += b" 255 128 0"
    else:  # the counts on the keyword's line, the edge count wrong
        keyword = next(i for i in range(start - 1) if lines[i].strip() and not lines[i].startswith(b"#"))
        lines[keyword] += b" " + b" ".join(lines[start - 1].split()[:2]) + b" 999"
        del lines[start - 1]


#: The edits of ``off-lines``, by name: each changes a seed OFF's lines in place (a list of bytes).
_OFF_LINE_EDITS = {
    "vertex-duplicated": _off_vertex_duplicated,
    "vertex-deleted": _off_vertex_deleted,
    "face-duplicated": _off_face_duplicated,
    "face-deleted": _off_face_deleted,
    "index-out-of-range": _off_index_out_of_range,
    "index-not-whole": _off_index_not_whole,
    "corner-count": _off_corner_count,
    "face-values": _off_face_values,
    "line-appended": _off_line_appended,
    "harmless": _off_harmless,
}


def off_line_edit(data: bytes, edit: str, rng) -> bytes:
    """Apply one edit of :data:`_OFF_LINE_EDITS` to a seed OFF (vertex and face lines without blank lines between)."""
    lines = data.split(b"\n")
    if next((True for line in lines if _OFF_COUNTS_LINE.fullmatch(line)), False):
        _OFF_LINE_EDITS[edit](lines, rng)
    return b"\n".join(lines)


@_mutator("off-lines", families=("off",))
def _off_lines(data, rng):
    return off_line_edit(data, _pick(rng, sorted(_OFF_LINE_EDITS)), rng)


def _obj_face_lines(lines):
    return [i for i, line in enumerate(lines) if line.startswith(b"f ")]


def _obj_corner(lines, rng, value):
    """Replace the vertex index of a random corner of a random face with ``value``."""
    k = _pick(rng, _obj_face_lines(lines))
    tokens = lines[k].split()
    at = 1 + int(rng.integers(len(tokens) - 1))
    tokens[at] = value + tokens[at][len(tokens[at].split(b"/")[0]):]
    lines[k] = b" ".join(tokens)


def _obj_vertex_deleted(lines, rng):
    vertices = [i for i, line in enumerate(lines) if line.startswith(b"v ")]
    del lines[vertices[-1] if rng.random() < 0.5 else _pick(rng, vertices)]


def _obj_relative(lines, rng):
    """Every face's vertex indices made relative (negative): a valid file."""
    n_vertices = sum(line.startswith(b"v ") for line in lines)
    for k in _obj_face_lines(lines):
        lines[k] = re.sub(rb"(?<= )(\d+)", lambda m: str(int(m.group(1)) - n_vertices - 1).encode(), lines[k])


#: The edits of ``obj-faces``, by name: each changes a seed OBJ's lines in place (a list of bytes).
_OBJ_FACE_EDITS = {
    "index-out-of-range": lambda lines, rng: _obj_corner(lines, rng, str(N_SEED + 1).encode()),
    "index-before-the-start": lambda lines, rng: _obj_corner(lines, rng, str(-N_SEED - 1).encode()),
    "index-zero": lambda lines, rng: _obj_corner(lines, rng, b"0"),
    "index-not-whole": lambda lines, rng: _obj_corner(lines, rng, _pick(rng, [b"1.5", b"x", b""])),
    "corner-malformed": lambda lines, rng: _obj_corner(lines, rng, b"1/2/3/4"),
    "vertex-deleted": _obj_vertex_deleted,
    "relative": _obj_relative,
}


def obj_face_edit(data: bytes, edit: str, rng) -> bytes:
    """Apply one edit of :data:`_OBJ_FACE_EDITS` to a seed OBJ (``v`` and ``f`` lines)."""
    lines = data.split(b"\n")
    if _obj_face_lines(lines):
        _OBJ_FACE_EDITS[edit](lines, rng)
    return b"\n".join(lines)


@_mutator("obj-faces", families=("obj",))
def _obj_faces(data, rng):
    return obj_face_edit(data, _pick(rng, sorted(_OBJ_FACE_EDITS)), rng)


@_mutator("off-keyword", families=("off",))
def _off_keyword(data, rng):
    word = _pick(rng, [b"OFF", b"NOFF", b"CNOFF", b"STOFF", b"4OFF", b"nOFF", b"OFF BINARY", b"off", b"",
                       b"COFF 120 118 0", b"STCNOFF"])
    return re.sub(rb"^\S*OFF", word, data, count=1)


@_mutator("pts-count", families=("pts",))
def _pts_count(data, rng):
    value = _pick(rng, [str(v).encode() for v in _INTERESTING] + [b"-5", b"abc", b"1.5", b"", b"10" * 20])
    if rng.random() < 0.3:  # a second scan's count line in the middle
        at = data.find(b"\n", _position(rng, data)) + 1
        return data[:at] + value + b"\n" + data[at:]
    return re.sub(rb"^[^\n]*", value, data, count=1)


# --- NPY headers and NPZ archives
def npy_header(data: bytes) -> tuple:
    """An NPY file's header dict (literally evaluated) and the bytes after it."""
    hlen_size = 2 if data[6:7] == b"\x01" else 4
    hlen = int.from_bytes(data[8: 8 + hlen_size], "little")
    start = 8 + hlen_size
    return ast.literal_eval(data[start: start + hlen].decode("latin-1")), data[start + hlen:]


def _npy_bytes(header, body, stale=None):
    text = (header if isinstance(header, str) else repr(header)).encode("latin-1")
    text += b" " * ((-(len(text) + 11)) % 64) + b"\n"
    size = len(text) if stale is None else stale
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", size & 0xFFFF) + text + body


@_mutator("npy-header", families=("npy",))
def _npy_header(data, rng):
    header, body = npy_header(data)
    n = header["shape"][0]
    edit = int(rng.integers(6))
    if edit == 0:
        header["shape"] = _pick(rng, [(0, 6), (2**62, 6), (n,), (6, n), (-1, 6), (n, 6, 1), (), (n, 2), (n - 1, 6),
                                      (n + 1, 6), (2**31, 3), (n, 2**40)])
    elif edit == 1:
        header["descr"] = _pick(rng, ["<f2", "|O", "<c16", ">f8", "<U8", "|S3", "|V48", "<M8[s]", "<f16", "x",
                                      [("x", "<f8"), ("y", "<f8"), ("z", "<f8")], [("x", "<f8")] * 2])
    elif edit == 2:
        header["fortran_order"] = _pick(rng, [True, 1, "yes", None])
    elif edit == 3:
        del header[_pick(rng, sorted(header))]
    elif edit == 4:
        header = _pick(rng, ["[1, 2]", "{'descr': '<f8'", "{'descr': '<f8', 'fortran_order': False, 'shape': "
                                      "(120, 6), 'x': __import__('os')}", "", "{" * 200 + "}" * 200])
    else:
        return _npy_bytes(header, body, stale=_pick(rng, [0, 1, 10, 65535, 2**15]))
    return _npy_bytes(header, body)


@_mutator("npy-version", families=("npy",))
def _npy_version(data, rng):
    return data[:6] + bytes(_pick(rng, [(2, 0), (3, 0), (0, 0), (9, 9), (1, 1)])) + data[8:]


def _zip(members, compression=zipfile.ZIP_STORED) -> bytes:
    buffer = io.BytesIO()
    with warnings.catch_warnings(), zipfile.ZipFile(buffer, "w", compression=compression) as archive:
        warnings.simplefilter("ignore")  # duplicate member names are on purpose
        for name, content in members:
            archive.writestr(name, content)
    return buffer.getvalue()


def _members(data):
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return [(name, archive.read(name)) for name in archive.namelist()]


def _npy_of(array) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=True)
    return buffer.getvalue()


@lru_cache(maxsize=4)
def _bomb(rows: int, stored_rows: int, copies: int = 1) -> bytes:
    """An NPZ whose ``points.npy`` says (rows, 3) float64 and inflates to ``stored_rows`` rows of zeros.

    ``copies > 1`` repeats the member's central-directory record (every copy points at the same
    data): NumPy loads each name of the directory, so the bomb inflates ``copies`` times.
    """
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=9) as archive:
        with archive.open("points.npy", "w", force_zip64=True) as member:
            header = f"{{'descr': '<f8', 'fortran_order': False, 'shape': ({rows}, 3), }}"
            member.write(_npy_bytes(header, b""))
            chunk = bytes(2**22)
            left = stored_rows * 24
            while left > 0:
                member.write(chunk[: min(left, len(chunk))])
                left -= len(chunk)
    data = buffer.getvalue()
    if copies == 1:
        return data
    central = data.find(b"PK\x01\x02")
    end = data.find(b"PK\x06\x06") if b"PK\x06\x06" in data else data.find(b"PK\x05\x06")
    record = data[central:end]
    out = data[:central] + record * copies
    return out + struct.pack("<4s4H2IH", b"PK\x05\x06", 0, 0, copies, copies, len(record) * copies, central, 0)


@_mutator("npz-bomb", families=("npz",))
def _npz_bomb(data, rng):
    kind = int(rng.integers(5))
    if kind == 0:  # honest bomb: 256 MiB of zeros in about 260 kB
        return _bomb(11_184_810, 11_184_810)
    if kind == 1:  # the header claims 2**40 rows, the member holds a few
        return _bomb(2**40, 40)
    if kind == 2:  # 64 MiB inflated 64 times through one member listed 64 times
        return _bomb(2_796_202, 2_796_202, 64)
    if kind == 3:  # 20000 tiny members
        return _zip(_members(data) + [(f"m{k}.npy", _npy_of(np.zeros(1))) for k in range(20000)])
    data = _zip(_members(data))  # without zip64 records, then every record announces 4 GiB uncompressed
    out = bytearray(data)
    for m in re.finditer(rb"PK\x03\x04", data):
        struct.pack_into("<I", out, m.start() + 22, 0xFFFFFFFF)
    return bytes(out)


@_mutator("npz-member", families=("npz",))
def _npz_member(data, rng):
    members = _members(data)
    points = dict(members).get("points.npy", b"")
    others = [(n, c) for n, c in members if n != "points.npy"]
    replacement = _pick(rng, [
        [("points.npy", b"x y z\n1 2 3\n")], [("points.npy", _npy_of(np.array([None, 1], dtype=object)))],
        [("points.npy", _zip(members))], [("points", points)], [("points.npy", points)] * 2,
        [("points/", b"")], [("points.npy", _npy_of(np.zeros((N_SEED, 2))))],
        [("points.npy", _npy_of(np.array(1.0)))], [("points.npy", _npy_of(np.zeros((N_SEED, 3), complex)))],
        [("xyz.npy", points)], [("../points.npy", points)], [("notes.txt", b"hello")] + [("points.npy", points)],
        [("points.npy", _npy_of(np.zeros(N_SEED, dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])))],
        [("points.npy", points), ("nx.npy", _npy_of(np.zeros(7))), ("colors.npy", _npy_of(np.zeros((2, 3))))],
        [("points.npy", _npy_of(np.zeros((1, 3))))],  # one point beside the seed's 120-row fields
    ])
    return _zip(others + replacement, _pick(rng, [zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED]))


@_mutator("npz-member-npy", families=("npz",))
def _npz_member_npy(data, rng):
    members = _members(data)
    mutator = _pick(rng, [_npy_header, _npy_version, _truncate_random, _flip_bits])
    k = _pick(rng, [i for i, (name, _) in enumerate(members) if name == "points.npy"] or [0])
    members[k] = (members[k][0], mutator(members[k][1], rng))
    return _zip(members)


@_mutator("zip-fields", families=("npz",))
def _zip_fields(data, rng):
    """Compression method, flags and sizes of the zip records."""
    out = bytearray(data)
    starts = [m.start() for m in re.finditer(rb"PK\x01\x02|PK\x03\x04", data)]
    at = _pick(rng, starts)
    central = data[at:at + 4] == b"PK\x01\x02"
    field_at, fmt, values = _pick(rng, [
        (10 if central else 8, "<H", [1, 6, 12, 14, 99, 0xFFFF]),  # compression method
        (8 if central else 6, "<H", [1, 0x41, 0x2000, 0xFFFF]),  # flags: encrypted, strong encryption
        (24 if central else 22, "<I", [0, 1, 0xFFFFFFFF, 2**31]),  # uncompressed size
        (20 if central else 18, "<I", [0, 1, 0xFFFFFFFF]),  # compressed size
        (28 if central else 26, "<H", [0, 0xFFFF]),  # name length
    ])
    struct.pack_into(fmt, out, at + field_at, _pick(rng, values))
    return bytes(out)


# --- LAS and LAZ headers
def _pack(data, fmt, offset, value):
    out = bytearray(data)
    if offset + struct.calcsize(fmt) <= len(out):
        struct.pack_into(fmt, out, offset, value)
    return bytes(out)


@_mutator("las-point-count", families=("las", "laz"))
def _las_point_count(data, rng):
    value = _pick(rng, [0, 1, N_SEED - 1, N_SEED + 1, 2 * N_SEED] + _INTERESTING[5:])
    which = int(rng.integers(3)) if data[25] >= 4 else 0
    if which in (0, 2):
        data = _pack(data, "<I", 107, value & 0xFFFFFFFF)
    if which in (1, 2):
        data = _pack(data, "<Q", 247, value)
    return data


@_mutator("las-vlr-count", families=("las", "laz"))
def _las_vlr_count(data, rng):
    vlrs = struct.unpack_from("<I", data, 100)[0]
    return _pack(data, "<I", 100, _pick(rng, [0, max(vlrs - 1, 0), vlrs + 1, vlrs + 1000, 2**31, 2**32 - 1]))


@_mutator("las-point-offset", families=("las", "laz"))
def _las_point_offset(data, rng):
    header_size, offset = struct.unpack_from("<HI", data, 94)
    value = _pick(rng, [0, 1, 226, header_size - 1, header_size, offset - 1, offset + 1, offset + 54,
                        len(data), len(data) + 1000, 2**32 - 1])
    return _pack(data, "<I", 96, value % 2**32)


@_mutator("las-record-length", families=("las", "laz"))
def _las_record_length(data, rng):
    record = struct.unpack_from("<H", data, 105)[0]
    return _pack(data, "<H", 105, _pick(rng, [0, 1, record - 1, record + 1, 2 * record, 65535]))


@_mutator("las-scale", families=("las", "laz"))
def _las_scale(data, rng):
    value = _pick(rng, [0.0, -0.0, float("nan"), float("inf"), float("-inf"), -1e-3, 1e-300, 1e300, 5e-324])
    return _pack(data, "<d", 131 + 8 * int(rng.integers(3)), value)


@_mutator("las-offset-bbox", families=("las", "laz"))
def _las_offset_bbox(data, rng):
    field = int(rng.integers(9))  # the 3 offsets, then max x, min x, max y, min y, max z, min z
    if rng.random() < 0.4 and field >= 3 and len(data) >= 227:  # a box that leaves points out
        high, low = struct.unpack_from("<2d", data, 179 + 16 * ((field - 3) // 2))
        return _pack(data, "<d", 155 + 8 * field, low + (high - low) * _pick(rng, [0.25, 0.5, 0.9]))
    value = _pick(rng, [float("nan"), float("inf"), -float("inf"), 1e308, -1e308])
    return _pack(data, "<d", 155 + 8 * field, value)


@_mutator("las-format", families=("las", "laz"))
def _las_format(data, rng):
    edit = int(rng.integers(3))
    if edit == 0:  # point format id, with or without the compression bits
        return _pack(data, "<B", 104, int(rng.integers(256)))
    if edit == 1:  # version
        return data[:24] + bytes(_pick(rng, [(1, 0), (1, 5), (2, 0), (9, 9), (0, 0), (1, 4), (1, 2)])) + data[26:]
    return _pack(data, "<H", 94, _pick(rng, [0, 100, 226, 227, 374, 375, 376, 65535]))  # header size


@_mutator("las-vlr", families=("las", "laz"))
def _las_vlr(data, rng):
    header_size, _, vlrs = struct.unpack_from("<HII", data, 94)
    if vlrs == 0 or rng.random() < 0.3:  # extended VLRs (LAS 1.4)
        return _pack(_pack(data, "<Q", 235, _pick(rng, [0, 1, len(data) - 10, len(data), 2**63 - 1])),
                     "<I", 243, _pick(rng, [0, 1, 1000, 2**32 - 1]))
    return _pack(data, "<H", header_size + 20, _pick(rng, [0, 1, 65535, 1000]))  # first VLR's length


@_mutator("las-point-format", families=("las", "laz"))
def _las_point_format(data, rng):
    """Another point format with the same record length: the standard fields move, the extra bytes with them."""
    current = data[104] & 0x3F if len(data) > 104 else 0
    choices = [f for f in (0, 1, 2, 3, 6, 7, 8) if f != current]
    return _pack(data, "<B", 104, _pick(rng, choices) | (data[104] & 0xC0))


@_mutator("las-misalign", families=("las", "laz"))
def _las_misalign(data, rng):
    """Bytes inserted in the points, VLR bytes duplicated, or records shifted with the file's size kept."""
    header_size, offset = struct.unpack_from("<HI", data, 94)
    record = max(1, struct.unpack_from("<H", data, 105)[0])
    inside = offset + record * int(rng.integers(N_SEED)) + int(rng.integers(record))
    edit = int(rng.integers(3))
    if edit == 0:  # 1 to a record's length of bytes inside the points
        return data[:inside] + rng.bytes(_pick(rng, [1, 6, record - 1, record])) + data[inside:]
    if edit == 1:  # a block of the VLRs duplicated: the offset to the points now falls inside a VLR
        start = header_size + _position(rng, data[header_size:offset])
        block = data[start: start + int(rng.integers(1, 129))]
        return data[:start] + block + data[start:]
    return (data[:inside] + rng.bytes(int(rng.integers(1, record))) + data[inside:])[: len(data)]


def _laszip_vlr(data):
    """Offset of the laszip VLR's payload, or None."""
    header_size, _, vlrs = struct.unpack_from("<HII", data, 94)
    at = header_size
    for _ in range(min(vlrs, 100)):
        if at + 54 > len(data):
            return None
        user, length = data[at + 2: at + 18], struct.unpack_from("<H", data, at + 20)[0]
        if user.rstrip(b"\x00") == b"laszip encoded":
            return at + 54
        at += 54 + length
    return None


@_mutator("laz-chunk-table", families=("laz",))
def _laz_chunk_table(data, rng):
    offset = struct.unpack_from("<I", data, 96)[0]
    table = struct.unpack_from("<q", data, offset)[0] if offset + 8 <= len(data) else 0
    edit = int(rng.integers(3))
    if edit == 0:  # the table's offset
        return _pack(data, "<q", offset, _pick(rng, [-1, 0, 8, offset, table - 1, len(data), len(data) + 10**6,
                                                     2**63 - 1]))
    if edit == 1 and 0 < table < len(data) - 8:  # the number of chunks
        return _pack(data, "<I", table + 4, _pick(rng, [0, 2, 1000, 2**16, 2**31, 2**32 - 1]))
    if 0 < table < len(data) - 8:  # the table's version
        return _pack(data, "<I", table, _pick(rng, [1, 2**31, 2**32 - 1]))
    return data


@_mutator("laz-vlr", families=("laz",))
def _laz_vlr(data, rng):
    at = _laszip_vlr(data)
    if at is None:
        return data
    offset, fmt, values = _pick(rng, [
        (0, "<H", [0, 1, 2, 3, 4, 99]),  # compressor
        (12, "<I", [0, 1, 2**31, 2**32 - 1]),  # chunk size
        (32, "<H", [0, 1, 100, 65535]),  # number of items
        (34, "<H", [0, 99, 65535]),  # first item's type
        (36, "<H", [0, 1, 255, 65535]),  # first item's size
        (40, "<H", [0, 7, 8, 11, 12, 14]),  # second item's type: another format's item of the same size
    ])
    return _pack(data, fmt, at + offset, _pick(rng, values))


def mutate(data: bytes, mutator: str, case_seed: int) -> bytes:
    """Apply one mutator of :data:`MUTATORS` to a file's bytes.

    Parameters
    ----------
    data : bytes
        The seed file's contents.
    mutator : str
        A key of :data:`MUTATORS`.
    case_seed : int
        Seeds the mutator's random choices (``numpy.random.default_rng``):
        the same seed gives the same bytes.

    Returns
    -------
    bytes
    """
    return MUTATORS[mutator](data, np.random.default_rng(case_seed))
