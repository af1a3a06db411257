"""Structural checks of a LAS/LAZ file before laspy and lazrs decode it (untrusted files).

laspy and lazrs trust the sizes and counts a file declares: a VLR count of
0xFFFFFFFF makes laspy loop for minutes, a chunk count of 0xFFFFFFFF makes
lazrs reserve 68 GB and abort the process, a flipped byte in a layer size or
a point count makes them allocate gigabytes for a file of a few kilobytes.
:func:`check_las_file` reads the public header, walks the VLRs and EVLRs and,
for LAZ, reads the laszip VLR, the chunk table and the head of every chunk,
and checks every size and count against the file size, so that what laspy
and lazrs allocate afterwards stays proportional to the file:

- every byte is accounted for: the point record length is the point format's
  size plus the extra bytes the ExtraBytes VLR describes; the bytes between the
  last VLR and the points hold no further VLR (the VLR count left one out);
  uncompressed points take exactly ``point_count * record_length`` bytes up to
  the extended VLRs (LAS 1.3: the waveform record) or the end of the file, and
  the extended VLRs end where the file ends;
- the header's numbers are usable: scales non-zero, finite, a normal number no
  finer than double precision resolves at the coordinates' magnitude, and not
  so coarse that a record's integer leaves the double range; offsets and
  bounding box finite, each minimum at most its maximum;
- LAZ: the laszip items are those of the header's point format (plus the
  extra bytes); the point count is at most :data:`MAX_POINTS_PER_COMPRESSED_BYTE`
  times the compressed bytes; the chunk count matches the point count and the
  chunk size; the chunk table's byte counts add up to the compressed data; every
  layer size of a layered (LAS 1.4 formats 6-10) chunk fits in its chunk;
  a fixed chunk size far beyond the point count selects lazrs's sequential
  decoder (the parallel one allocates a whole chunk for the last one);
- whatever the counts, the decompressed points must fit in the machine's
  physical memory.

After decoding, :func:`check_points_in_box` checks every point against the
header's bounding box (one scale step of rounding allowed).

Layouts: ASPRS LAS 1.4 R15 (public header, VLR and EVLR headers) and the LAZ
format as written by LASzip and lazrs (laszip VLR, chunk table, layered chunks).
"""

from __future__ import annotations

import math
import os
import struct
import sys
from dataclasses import dataclass

import numpy as np

from ._common import _one_line

# smallest public header laspy accepts for each minor version 0..5
_HEADER_SIZE = {0: 227, 1: 227, 2: 227, 3: 235, 4: 375, 5: 393}
# bytes of a point record of each point format 0..10
_FORMAT_SIZE = (20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67)
_VLR_HEADER = 54
_EVLR_HEADER = 60
_LASZIP_USER_ID = b"laszip encoded"
_LASZIP_RECORD_ID = 22204
_SPEC_USER_ID = b"LASF_Spec"
_EXTRA_BYTES_RECORD_ID = 4
_EXTRA_BYTES_DESCRIPTOR = 192
# bytes of the extra-bytes data types 1..10; types 11..20 and 21..30 are deprecated 2- and 3-element arrays of them
_EXTRA_TYPE_SIZE = (1, 1, 2, 2, 4, 4, 8, 8, 4, 8)
# what LAS 1.0-1.2 writers (and LAStools) put between the VLRs and the points: the point data start signature
_POINT_SIGNATURE = b"\xdd\xcc"
# laszip item types: the items of each point format 0..10, extra bytes aside (BYTE 0, BYTE14 14)
_ITEM_NAMES = {6: "POINT10", 7: "GPSTIME11", 8: "RGB12", 9: "WAVEPACKET13", 10: "POINT14", 11: "RGB14",
               12: "RGBNIR14", 13: "WAVEPACKET14"}
_EXTRA_ITEMS = (0, 14)
_FORMAT_ITEMS = ((6,), (6, 7), (6, 8), (6, 7, 8), (6, 7, 9), (6, 7, 8, 9), (10,), (10, 11), (10, 12), (10, 13),
                 (10, 12, 13))
# the largest magnitude of a record's 32-bit coordinate integer
_LARGEST_INTEGER = 2.0**31
_VARIABLE_CHUNKS = 0xFFFFFFFF
# layers of a layered (LAZ v3/v4) item, by item type; Byte14 has one per byte
_LAYERS = {10: 9, 11: 1, 12: 2, 13: 1}
_BYTE14 = 14

#: The most points a LAZ file may announce per byte of compressed point data.
#: LAZ's arithmetic coder cannot code a point in much less than ~0.01 bit: its
#: adaptive models cap the probability of the likeliest symbol (15-bit
#: distributions, counts halved at 2**16), and each point codes at least 4-8
#: symbols. Measured with lazrs on the most compressible data there is (all
#: points identical, one 10-million-point chunk): 671 points per byte (format
#: 0), 640 (1), 388-399 (2, 3), 503 (formats 6-10, extra bytes free when
#: constant); with the default 50 000-point chunks at most 148. 4096 is 6x the
#: best measured and about twice a rough floor of the coder, so no real file
#: is refused, while a flipped count byte in a 7 kB file can no longer ask for
#: more than a few hundred megabytes.
MAX_POINTS_PER_COMPRESSED_BYTE = 4096

#: Bytes a LAZ writer may leave after the chunk table: liblas leaves 32 (the other writers measured, none).
CHUNK_TABLE_SLACK = 32

#: Above this, a fixed chunk size larger than the point count selects lazrs's
#: sequential decoder: the parallel one allocates ``chunk_size * record_length``
#: bytes for the last chunk whatever the number of points in it.
_PARALLEL_LAST_CHUNK_BYTES = 64 << 20


class LasStructureError(ValueError):
    """The file contradicts itself or its size; the message says how, in plain words."""


@dataclass(frozen=True)
class LasLayout:
    """What the checked header declares."""

    version: tuple[int, int]
    point_format: int
    record_length: int
    point_count: int
    compressed: bool
    #: LAZ: decode with lazrs's sequential decoder instead of the parallel one
    sequential: bool = False
    file_size: int = 0
    scales: tuple = (1.0, 1.0, 1.0)
    offsets: tuple = (0.0, 0.0, 0.0)
    #: the header's bounding box, ((min, max) of X, of Y, of Z)
    box: tuple = ()


def _plural(count: int, word: str) -> str:
    return f"{count} {word}" if count == 1 else f"{count} {word}s"


def _size(n: int) -> str:
    """Bytes in words: '3.1 GB', '640 kB', '12 bytes'."""
    for unit, factor in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= factor:
            return f"{n / factor:.3g} {unit}"
    return _plural(n, "byte")


def _physical_memory() -> int | None:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # not on this platform
        return None


class _Reader:
    """Reads byte ranges of the open file; the ranges are checked against its size first."""

    def __init__(self, stream, size: int):
        self.stream = stream
        self.size = size

    def read(self, position: int, count: int) -> bytes:
        self.stream.seek(position)
        data = self.stream.read(count)
        if len(data) != count:  # the file shrank while being read
            raise LasStructureError(f"truncated: byte {position + count} is past the end of the file")
        return data


def _user_id(raw: bytes, what: str) -> str:
    """The user id as laspy decodes it (UTF-8 up to the first NUL), or a plain error."""
    head = raw.split(b"\0")[0]
    try:
        return head.decode()
    except UnicodeDecodeError:
        raise LasStructureError(f"the user id of {what} is not text ({head[:16]!r})") from None


def _walk_vlrs(reader: _Reader, start: int, end: int, count: int) -> tuple:
    """Check the ``count`` VLRs between ``start`` and ``end``.

    Returns
    -------
    laszip, extra_bytes : bytes or None
        The data of the laszip VLR, and of the ExtraBytes VLRs put together (laspy reads them all).
    position : int
        Where the last VLR ends.
    """
    room = (end - start) // _VLR_HEADER
    if count > room:
        raise LasStructureError(
            f"the header announces {count} VLRs, the {_plural(end - start, 'byte')} between "
            f"the header and the point data hold at most {room}"
        )
    laszip = extra_bytes = None
    position = start
    for k in range(count):
        what = f"VLR {k + 1} of {count}"
        if position + _VLR_HEADER > end:
            raise LasStructureError(
                f"{what} would start at byte {position}, in or past the point data (byte {end})"
            )
        head = reader.read(position, _VLR_HEADER)
        user_id = _user_id(head[2:18], what)
        record_id, length = struct.unpack_from("<HH", head, 18)
        if position + _VLR_HEADER + length > end:
            raise LasStructureError(
                f"{what} ({user_id!r}, record {record_id}) announces {length} bytes of data, "
                f"running past the start of the point data (byte {end})"
            )
        raw_user_id = head[2:18].split(b"\0")[0]
        if raw_user_id == _LASZIP_USER_ID and record_id == _LASZIP_RECORD_ID:
            laszip = reader.read(position + _VLR_HEADER, length)
        if raw_user_id == _SPEC_USER_ID and record_id == _EXTRA_BYTES_RECORD_ID:
            extra_bytes = (extra_bytes or b"") + reader.read(position + _VLR_HEADER, length)
        position += _VLR_HEADER + length
    return laszip, extra_bytes, position


def _hidden_vlrs(reader: _Reader, start: int, end: int) -> list:
    """The VLRs that fill the bytes from ``start`` to ``end`` (the points), if they are VLRs.

    Real writers leave zeros, the 2-byte point data start signature or leftovers
    of their memory between the last VLR and the points; a chain of VLR headers
    (a text user id, NUL-padded) that ends exactly at the points (or at the
    signature before them) is VLRs the header's VLR count leaves out.

    Returns
    -------
    list of (str, int)
        The user id and record id of each, or an empty list.
    """
    found = []
    position = start
    while position + _VLR_HEADER <= end and len(found) < 64:
        head = reader.read(position, _VLR_HEADER)
        user_id = head[2:18].split(b"\0")[0]
        if not user_id or not all(32 <= c < 127 for c in user_id) or head[2 + len(user_id):18].strip(b"\0"):
            return []
        record_id, length = struct.unpack_from("<HH", head, 18)
        found.append((user_id.decode(), record_id))
        position += _VLR_HEADER + length
        if position == end or (position == end - 2 and reader.read(position, 2) == _POINT_SIGNATURE):
            return found
    return []


def _described_extra_bytes(data: bytes | None) -> int:
    """The bytes per point an ExtraBytes VLR's descriptors describe (laspy's reading of their types)."""
    if data is None:
        return 0
    if len(data) % _EXTRA_BYTES_DESCRIPTOR:
        raise LasStructureError(
            f"the ExtraBytes VLR holds {_plural(len(data), 'byte')}, not a whole number of "
            f"{_EXTRA_BYTES_DESCRIPTOR}-byte descriptors"
        )
    total = 0
    for k in range(len(data) // _EXTRA_BYTES_DESCRIPTOR):
        data_type, options = data[_EXTRA_BYTES_DESCRIPTOR * k + 2], data[_EXTRA_BYTES_DESCRIPTOR * k + 3]
        if data_type == 0:  # undocumented bytes: their number is the options field
            total += options
        elif data_type <= 30:
            total += _EXTRA_TYPE_SIZE[(data_type - 1) % 10] * ((data_type - 1) // 10 + 1)
        else:
            raise LasStructureError(
                f"extra dimension {k + 1} of the ExtraBytes VLR has the unknown data type {data_type}"
            )
    return total


def _walk_evlrs(reader: _Reader, start: int, count: int) -> int:
    """Check the ``count`` extended VLRs from ``start``; return where the last one ends."""
    room = (reader.size - start) // _EVLR_HEADER
    if count > room:
        raise LasStructureError(
            f"the header announces {count} extended VLRs, the {_plural(reader.size - start, 'byte')} "
            f"from byte {start} to the end of the file hold at most {room}"
        )
    position = start
    for k in range(count):
        what = f"extended VLR {k + 1} of {count}"
        if position + _EVLR_HEADER > reader.size:
            raise LasStructureError(
                f"truncated: {what} would start at byte {position}, the file has "
                f"{_plural(reader.size, 'byte')}"
            )
        head = reader.read(position, _EVLR_HEADER)
        user_id = _user_id(head[2:18], what)
        record_id, length = struct.unpack_from("<HQ", head, 18)
        if position + _EVLR_HEADER + length > reader.size:
            raise LasStructureError(
                f"{what} ({user_id!r}, record {record_id}) announces {length} bytes of data, "
                f"running past the end of the file ({_plural(reader.size, 'byte')})"
            )
        position += _EVLR_HEADER + length
    return position


def _check_numbers(scales, offsets, box) -> None:
    """Scales, offsets and the bounding box: finite, and scales that resolve distinct coordinates.

    A record's coordinate is ``integer * scale + offset`` in double precision:
    a scale below the double spacing at the coordinates' magnitude (or a
    subnormal one) maps every integer onto the same few values, the axis
    collapses onto its offset; a scale whose ``2**31`` multiple overflows
    gives infinite coordinates.
    """
    for axis, scale, offset, (low, high) in zip("XYZ", scales, offsets, box):
        if scale == 0:
            raise LasStructureError(
                f"the {axis} scale factor is 0: every {axis} coordinate would be 0"
            )
        if not math.isfinite(scale):
            raise LasStructureError(f"the {axis} scale factor is {scale}, not a finite number")
        if not math.isfinite(offset):
            raise LasStructureError(f"the {axis} offset is {offset}, not a finite number")
        if not (math.isfinite(low) and math.isfinite(high)):
            raise LasStructureError(
                f"the header's bounding box is not finite ({axis} from {low} to {high})"
            )
        if low > high:
            raise LasStructureError(
                f"the header's bounding box has an {axis} minimum ({low:.10g}) above its maximum ({high:.10g})"
            )
        step = abs(scale)
        magnitude = max(abs(offset), abs(low), abs(high))
        if step < max(sys.float_info.min, sys.float_info.epsilon * magnitude):
            raise LasStructureError(
                f"the {axis} scale factor {scale:.3g} is finer than double precision resolves at the "
                f"coordinates' magnitude ({magnitude:.3g}): every {axis} would collapse onto a few values "
                f"around the offset"
            )
        if not math.isfinite(abs(offset) + step * _LARGEST_INTEGER):
            raise LasStructureError(
                f"the {axis} scale factor {scale:.3g} is so large that a record's {axis} can be beyond the "
                "range of double precision"
            )


@dataclass(frozen=True)
class _LasZip:
    compressor: int
    chunk_size: int
    items: tuple  # (type, size, version)
    record_data: bytes


def _parse_laszip(data: bytes | None, record_length: int) -> _LasZip:
    if data is None:
        raise LasStructureError(
            "the point format says compressed (LAZ), but the laszip VLR that describes "
            "the compression is missing"
        )
    if len(data) < 34:
        raise LasStructureError(
            f"the laszip VLR is too short ({_plural(len(data), 'byte')}, at least 34)"
        )
    compressor, _coder = struct.unpack_from("<HH", data, 0)
    chunk_size = struct.unpack_from("<I", data, 12)[0]
    num_items = struct.unpack_from("<H", data, 32)[0]
    if len(data) != 34 + 6 * num_items:
        raise LasStructureError(
            f"the laszip VLR holds {_plural(len(data), 'byte')}, its {_plural(num_items, 'item')} "
            f"need {34 + 6 * num_items}"
        )
    items = tuple(struct.unpack_from("<HHH", data, 34 + 6 * k) for k in range(num_items))
    if compressor == 1:
        raise LasStructureError(
            "the points use the old point-wise LAZ compression (laszip compressor 1), "
            "which lazrs cannot read"
        )
    if compressor not in (2, 3):
        raise LasStructureError(f"the laszip VLR names an unknown compressor ({compressor})")
    item_bytes = sum(size for _type, size, _version in items)
    if item_bytes != record_length:
        raise LasStructureError(
            f"the laszip VLR describes points of {_plural(item_bytes, 'byte')}, "
            f"the header says {record_length}"
        )
    if chunk_size == 0:
        raise LasStructureError("the laszip VLR's chunk size is 0")
    return _LasZip(compressor, chunk_size, items, bytes(data))


def _check_items(laszip: _LasZip, point_format: int) -> None:
    """The laszip items must be those of the header's point format (the extra bytes aside)."""
    kinds = tuple(item_type for item_type, _size, _version in laszip.items if item_type not in _EXTRA_ITEMS)
    expected = _FORMAT_ITEMS[point_format]
    if kinds != expected:
        def names(types):
            return " ".join(_ITEM_NAMES.get(t, f"type {t}") for t in types) or "no point"
        raise LasStructureError(
            f"the laszip VLR compresses {names(kinds)} items, point format {point_format} is "
            f"{names(expected)}: the header's point format is not the compressed one"
        )


def _read_chunk_table(reader: _Reader, start_of_points: int, laszip: _LasZip):
    """The chunk table as lazrs reads it: [(point_count, byte_count)] per chunk."""
    import lazrs

    try:
        vlr = lazrs.LazVlr(laszip.record_data)
    except Exception as exc:
        raise LasStructureError(f"the laszip VLR is corrupt (lazrs: {_one_line(exc)})") from None
    try:
        reader.stream.seek(start_of_points)
        return lazrs.read_chunk_table(reader.stream, vlr)
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as exc:  # lazrs errors, and pyo3 panics (not Exceptions)
        raise LasStructureError(
            f"the chunk table is corrupt or truncated (lazrs: {_one_line(exc)})"
        ) from None


def _chunk_table_length(table_bytes: bytes, laszip: _LasZip, entries) -> int:
    """The bytes of ``table_bytes`` the chunk table takes: the shortest prefix that decodes to ``entries``.

    The table's entries are arithmetic-coded, so its length is not stored;
    lazrs fails on a prefix cut inside it and reads the whole table from
    exactly the bytes its encoder wrote.
    """
    import io

    import lazrs

    vlr = lazrs.LazVlr(laszip.record_data)

    def decodes(length: int) -> bool:
        try:
            return lazrs.read_chunk_table(io.BytesIO(struct.pack("<q", 8) + table_bytes[:length]), vlr) == entries
        except (KeyboardInterrupt, SystemExit):
            raise
        except BaseException:  # lazrs errors, pyo3 panics
            return False

    low, high = 8, len(table_bytes)
    while low < high:
        middle = (low + high) // 2
        if decodes(middle):
            high = middle
        else:
            low = middle + 1
    return low


def _check_laz(
    reader: _Reader, offset: int, end: int, point_count: int, record_length: int, laszip: _LasZip
) -> bool:
    """Check the compressed points between ``offset`` and ``end``; whether to decode sequentially."""
    table, end_of_table = _chunk_table_start(reader, offset, end)
    compressed = table - (offset + 8)
    limit = MAX_POINTS_PER_COMPRESSED_BYTE * compressed
    if point_count > limit:
        raise LasStructureError(
            f"the header announces {point_count} points, far more than the "
            f"{_plural(compressed, 'byte')} of compressed points can hold (LAZ stores at most "
            f"about 700 points per byte; allowed: {limit})"
        )
    number_of_chunks = struct.unpack("<I", reader.read(table + 4, 4))[0]
    _check_chunk_count(number_of_chunks, point_count, compressed, record_length, laszip.chunk_size)
    entries = _read_chunk_table(reader, offset, laszip)
    if len(entries) != number_of_chunks:
        raise LasStructureError(
            f"the chunk table lists {number_of_chunks} chunks but holds {len(entries)}"
        )
    total = sum(byte_count for _points, byte_count in entries)
    if total != compressed:
        raise LasStructureError(
            f"the chunk table gives {_plural(total, 'byte')} of compressed points, "
            f"the file holds {compressed} before the table"
        )
    if table < end_of_table:
        spare = end_of_table - table - _chunk_table_length(reader.read(table, end_of_table - table), laszip, entries)
        if spare > CHUNK_TABLE_SLACK:
            where = "the extended VLRs" if end < reader.size else "the end of the file"
            raise LasStructureError(
                f"the {_plural(spare, 'byte')} between the chunk table and {where} are unexplained "
                f"(a LAZ writer leaves at most {CHUNK_TABLE_SLACK})"
            )
    chunk_size = laszip.chunk_size
    variable = chunk_size == _VARIABLE_CHUNKS
    if variable:
        counts = [points for points, _bytes in entries]
        if sum(counts) != point_count:
            raise LasStructureError(
                f"the chunk table counts {sum(counts)} points, the header {point_count}"
            )
    else:
        counts = [chunk_size] * (number_of_chunks - 1)
        counts.append(point_count - chunk_size * (number_of_chunks - 1))
    if laszip.compressor == 3 and all(
        item_type in _LAYERS or item_type == _BYTE14 for item_type, _s, _v in laszip.items
    ):
        _check_layers(reader, offset + 8, entries, counts, record_length, laszip)
    return not variable and chunk_size > point_count and (
        chunk_size * record_length > _PARALLEL_LAST_CHUNK_BYTES
    )


def _chunk_table_start(reader: _Reader, offset: int, end: int) -> tuple[int, int]:
    """Where the chunk table of the compressed points starts, and where its bytes end (``end``, or the table's
    offset stored at the end of the file by a streaming writer)."""
    size = reader.size
    if offset + 8 > end:
        raise LasStructureError(
            "truncated at the start of the compressed points (no room for the chunk table offset)"
        )
    table = struct.unpack("<q", reader.read(offset, 8))[0]
    end_of_table = end
    if table <= offset:
        # a streaming writer could not go back: lazrs then reads the offset at the end
        if size >= offset + 16:
            table = struct.unpack("<q", reader.read(size - 8, 8))[0]
            end_of_table = size - 8
        if table <= offset:
            raise LasStructureError(
                "the LAZ file has no chunk table (its writer could not store where the table "
                "is); lazrs cannot read such a file"
            )
    if table + 8 > size:
        raise LasStructureError(
            f"truncated: the chunk table of the compressed points would start at byte {table}, "
            f"the file has {_plural(size, 'byte')}"
        )
    if table < offset + 8 or table + 8 > end:
        raise LasStructureError(
            f"the chunk table of the compressed points would start at byte {table}, outside "
            f"the point data (bytes {offset + 8} to {end})"
        )
    return table, end_of_table


def _check_chunk_count(number_of_chunks: int, point_count: int, compressed: int, record_length: int,
                       chunk_size: int) -> None:
    """The chunk table's count of chunks against the points and the compressed bytes."""
    if number_of_chunks == 0:
        raise LasStructureError(f"the chunk table lists no chunks for {point_count} points")
    # every chunk starts with one raw point; lazrs ends variable chunks with an empty one
    most = compressed // record_length + 1
    if number_of_chunks > most:
        raise LasStructureError(
            f"the chunk table lists {number_of_chunks} chunks, the {_plural(compressed, 'byte')} "
            f"of compressed points hold at most {most} (each chunk starts with a "
            f"{record_length}-byte point)"
        )
    if chunk_size == _VARIABLE_CHUNKS:
        if number_of_chunks > point_count + 1:
            raise LasStructureError(
                f"the chunk table lists {number_of_chunks} chunks for only {point_count} points"
            )
    else:
        needed = -(-point_count // chunk_size)
        if number_of_chunks != needed:
            raise LasStructureError(
                f"the chunk table lists {number_of_chunks} chunks, {point_count} points in "
                f"chunks of {chunk_size} need {needed}"
            )


def _check_layers(reader, start, entries, counts, record_length, laszip) -> None:
    """Each layered chunk: a raw point, its point count, the layer sizes, the layers."""
    layers = sum(
        size if item_type == _BYTE14 else _LAYERS[item_type]
        for item_type, size, _version in laszip.items
    )
    head = record_length + 4 + 4 * layers
    position = start
    for k, ((_points, byte_count), points) in enumerate(zip(entries, counts)):
        what = f"chunk {k + 1} of {len(entries)}"
        if points == 0:  # an empty chunk (lazrs ends variable-size chunks with one): not decoded
            position += byte_count
            continue
        if byte_count < head:
            raise LasStructureError(
                f"{what} of the compressed points has {_plural(byte_count, 'byte')}, "
                f"less than its own {head}-byte head"
            )
        data = reader.read(position, head)
        stored = struct.unpack_from("<I", data, record_length)[0]
        if stored != points:
            raise LasStructureError(
                f"{what} of the compressed points says it holds {stored} points, "
                f"the chunk table and header give {points}"
            )
        sizes = struct.unpack_from(f"<{layers}I", data, record_length + 4)
        if sum(sizes) > byte_count - head:
            raise LasStructureError(
                f"{what} of the compressed points announces layers of "
                f"{_plural(sum(sizes), 'byte')} in {_plural(byte_count - head, 'byte')}"
            )
        position += byte_count


def check_las_file(path) -> LasLayout:
    """Check the structure of the LAS/LAZ file at ``path`` against its size.

    Returns
    -------
    LasLayout

    Raises
    ------
    LasStructureError
        The file contradicts itself or its size (message in plain words).
    OSError
        The file cannot be opened or read.
    """
    with open(path, "rb") as stream:
        size = os.fstat(stream.fileno()).st_size
        reader = _Reader(stream, size)
        head = stream.read(min(size, 393))
        header = _parse_header(head, size)
        laszip_data, extra_bytes_data, end_of_vlrs = _walk_vlrs(reader, header.size, header.offset, header.vlr_count)
        _check_no_hidden_vlrs(reader, header, end_of_vlrs)
        compressed = bool(header.raw_format & 0x80) and not header.raw_format & 0x40  # as laspy decides
        point_format = header.raw_format & 0x3F
        _check_record_length(point_format, header.record_length, extra_bytes_data)
        _check_numbers(header.scales, header.offsets, header.box)
        end_of_points = _end_of_points(reader, head, header, size, compressed)
        point_count, record_length = header.point_count, header.record_length
        layout = dict(
            version=header.version, point_format=point_format, record_length=record_length,
            point_count=point_count, compressed=compressed, file_size=size, scales=header.scales,
            offsets=header.offsets, box=header.box,
        )
        if point_count == 0:
            return LasLayout(**layout)
        sequential = False
        if compressed:
            laszip = _parse_laszip(laszip_data, record_length)
            _check_items(laszip, point_format)
            sequential = _check_laz(reader, header.offset, end_of_points, point_count, record_length, laszip)
        else:
            _check_point_data_size(header, end_of_points, size)
        memory = _physical_memory()
        if memory is not None and point_count * record_length > memory:
            raise LasStructureError(
                f"the header announces {point_count} points of {record_length} bytes "
                f"({_size(point_count * record_length)} decompressed), more than the "
                f"{_size(memory)} of memory of this machine"
            )
        return LasLayout(**layout, sequential=sequential)


@dataclass(frozen=True)
class _Header:
    """The fields of a LAS header that :func:`check_las_file` checks the file against."""

    version: tuple
    size: int
    offset: int
    vlr_count: int
    raw_format: int
    record_length: int
    point_count: int
    evlr_start: int
    evlr_count: int
    scales: tuple
    offsets: tuple
    box: tuple


def _parse_header(head: bytes, size: int) -> _Header:
    """The header's fields, checked against each other and against the file's ``size``."""
    if head[:4] != b"LASF":
        raise LasStructureError(f"not a LAS/LAZ file: it starts with {head[:4]!r}, not 'LASF'")
    if size < 227:
        raise LasStructureError(
            f"truncated inside the header ({_plural(size, 'byte')}; a LAS header takes at least 227)"
        )
    major, minor = head[24], head[25]
    if major != 1 or minor not in _HEADER_SIZE:
        raise LasStructureError(f"unsupported LAS version {major}.{minor} (laspy reads 1.0-1.5)")
    header_size, offset, vlr_count, raw_format, record_length, legacy_count = struct.unpack_from("<HIIBHI", head, 94)
    needed = _HEADER_SIZE[minor]
    if header_size < needed:
        raise LasStructureError(
            f"the header size field says {header_size} bytes, less than the {needed} of a LAS 1.{minor} header"
        )
    if size < header_size:
        raise LasStructureError(f"truncated inside the header (it takes {header_size} bytes, the file has {size})")
    if offset < header_size:
        raise LasStructureError(f"the point data would start at byte {offset}, inside the {header_size}-byte header")
    if offset > size:
        raise LasStructureError(
            f"truncated before the point data: it would start at byte {offset}, the file has {_plural(size, 'byte')}"
        )
    high_x, low_x, high_y, low_y, high_z, low_z = struct.unpack_from("<6d", head, 179)
    point_count, evlr_start, evlr_count = legacy_count, 0, 0
    if minor >= 4:
        evlr_start, evlr_count, point_count = struct.unpack_from("<QIQ", head, 235)
        if legacy_count not in (0, point_count):
            raise LasStructureError(
                f"the legacy point count ({legacy_count}) and the 64-bit point count "
                f"({point_count}) of the LAS 1.{minor} header disagree"
            )
    return _Header(
        version=(major, minor), size=header_size, offset=offset, vlr_count=vlr_count, raw_format=raw_format,
        record_length=record_length, point_count=point_count, evlr_start=evlr_start, evlr_count=evlr_count,
        scales=struct.unpack_from("<3d", head, 131), offsets=struct.unpack_from("<3d", head, 155),
        box=((low_x, high_x), (low_y, high_y), (low_z, high_z)),
    )


def _check_no_hidden_vlrs(reader: _Reader, header: _Header, end_of_vlrs: int) -> None:
    """Refuse VLRs between the counted ones and the points: a wrong VLR count."""
    hidden = _hidden_vlrs(reader, end_of_vlrs, header.offset)
    if hidden:
        names = ", ".join(f"{user_id!r} record {record_id}" for user_id, record_id in hidden[:3])
        after = "them" if header.vlr_count else "the header"
        raise LasStructureError(
            f"the header counts {_plural(header.vlr_count, 'VLR')}, but the "
            f"{_plural(header.offset - end_of_vlrs, 'byte')} after {after}, before the points, hold "
            f"{_plural(len(hidden), 'more VLR')} ({names}): the VLR count is wrong"
        )


def _check_record_length(point_format: int, record_length: int, extra_bytes_data) -> None:
    """The record length must be the point format's size plus the extra bytes its ExtraBytes VLR describes."""
    if point_format >= len(_FORMAT_SIZE):
        raise LasStructureError(f"unknown point format {point_format} (LAS defines formats 0 to 10)")
    if record_length < _FORMAT_SIZE[point_format]:
        raise LasStructureError(
            f"the point record length ({_plural(record_length, 'byte')}) is shorter than "
            f"the {_FORMAT_SIZE[point_format]} bytes of point format {point_format}"
        )
    described = _described_extra_bytes(extra_bytes_data)
    expected_length = _FORMAT_SIZE[point_format] + described
    if record_length != expected_length:
        if described:
            what = (f"the {_FORMAT_SIZE[point_format]} bytes of point format {point_format} plus the "
                    f"{described} its ExtraBytes VLR describes ({expected_length})")
        else:
            what = (f"the {_FORMAT_SIZE[point_format]} bytes of point format {point_format}, and no "
                    "ExtraBytes VLR describes the rest")
        raise LasStructureError(f"the point record length ({_plural(record_length, 'byte')}) is not {what}")


def _end_of_points(reader: _Reader, head: bytes, header: _Header, size: int, compressed: bool) -> int:
    """Where the point data ends: at the extended VLRs (checked to fill the rest of the file), else at the end."""
    minor, offset = header.version[1], header.offset
    end_of_points = end_of_evlrs = size
    if minor >= 4 and header.evlr_count > 0:
        if header.evlr_start < offset:
            raise LasStructureError(
                f"the extended VLRs would start at byte {header.evlr_start}, before the point data (byte {offset})"
            )
        if header.evlr_start > size:
            raise LasStructureError(
                f"truncated: the extended VLRs would start at byte {header.evlr_start}, "
                f"the file has {_plural(size, 'byte')}"
            )
        end_of_evlrs = _walk_evlrs(reader, header.evlr_start, header.evlr_count)
        end_of_points = header.evlr_start
    elif minor == 3:
        # LAS 1.3 keeps one extended VLR, the waveform data packets, after the points; a start inside
        # the points (the field was new in 1.3, some writers leave it unset) is not one
        waveform = struct.unpack_from("<Q", head, 227)[0]
        points_end = offset + (0 if compressed else header.point_count * header.record_length)
        if max(offset + 1, points_end) <= waveform < size:
            end_of_evlrs = _walk_evlrs(reader, waveform, 1)
            end_of_points = waveform
    if end_of_evlrs < size:
        raise LasStructureError(
            f"the {_plural(size - end_of_evlrs, 'byte')} after the last extended VLR (from byte "
            f"{end_of_evlrs} to the end of the file) are unexplained"
        )
    return end_of_points


def _check_point_data_size(header: _Header, end_of_points: int, size: int) -> None:
    """Uncompressed points must fill the point data exactly: no record missing, no byte unexplained."""
    offset, point_count, record_length = header.offset, header.point_count, header.record_length
    room = (end_of_points - offset) // record_length
    where = " before its extended VLRs" if end_of_points < size else ""
    if point_count > room:
        raise LasStructureError(
            f"truncated: the header announces {point_count} points of "
            f"{record_length} bytes, the file holds room for {room}{where}"
        )
    unexplained = end_of_points - offset - point_count * record_length
    if unexplained:
        hint = (f"room for {unexplained // record_length} more" if unexplained % record_length == 0
                else "not a whole number of records")
        raise LasStructureError(
            f"the point data{where} holds {_plural(end_of_points - offset, 'byte')}, "
            f"{unexplained} more than the {point_count} points of {record_length} bytes the header "
            f"announces ({hint}): the point count, the record length or the offset to the points is "
            "wrong, or bytes were inserted"
        )


def check_points_in_box(layout: LasLayout, points: np.ndarray, integers, first_record: int = 0) -> None:
    """Check decoded points against the header's bounding box, one scale step of rounding allowed.

    Records read from the wrong position (a count, a record length or an offset
    that shifts them) decode into coordinates far outside the box the header
    announces. Writers round the box or compute it from coordinates before
    they are put on the scale's grid, by up to one scale step; some (ALSXX_PP)
    store the box of the record integers, unscaled: a box that holds the
    integers themselves is accepted.

    Parameters
    ----------
    layout : LasLayout
        The checked header (:func:`check_las_file`).
    points : ndarray, shape (n, 3)
        The decoded coordinates.
    integers : sequence of 3 ndarrays, shape (n,)
        The records' X, Y and Z integers.
    first_record : int
        The file's index of the first of these points (a chunk of the file).

    Raises
    ------
    LasStructureError
        Naming the first point outside the box, by how much, and on which axis.
    """
    if not layout.box or points.shape[0] == 0:
        return
    low = np.array([lo for lo, _hi in layout.box]) - np.abs(layout.scales)
    high = np.array([hi for _lo, hi in layout.box]) + np.abs(layout.scales)
    outside = ((points < low) | (points > high)).any(axis=1)
    if not outside.any():
        return
    unscaled = all(
        np.all((np.asarray(values) >= lo - 1) & (np.asarray(values) <= hi + 1))
        for values, (lo, hi) in zip(integers, layout.box)
    )
    if unscaled:
        return
    first = int(np.argmax(outside))
    axis = int(np.argmax((points[first] < low) | (points[first] > high)))
    value = float(points[first, axis])
    lo, hi = layout.box[axis]
    side, word, bound = ("below", "minimum", lo) if value < lo else ("above", "maximum", hi)
    n = points.shape[0]
    rows = "" if first_record == 0 and n == layout.point_count else f" of records {first_record + 1}-{first_record + n}"
    name = "XYZ"[axis]
    raise LasStructureError(
        f"point record {first_record + first + 1} of {max(layout.point_count, first_record + points.shape[0])} lies "
        f"outside the header's bounding box: its {name} "
        f"({value:.10g}) is {abs(value - bound):.3g} {side} the box's {name} {word} ({bound:.10g}), more than "
        f"one scale step ({abs(layout.scales[axis]):.3g}); "
        f"{int(outside.sum())} of the {n} points{rows} are outside: the records are misaligned, or the header "
        "does not describe these points"
    )
