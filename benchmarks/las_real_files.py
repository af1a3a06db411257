"""Which real LAS/LAZ files pass each rule of heatcurv's LAS/LAZ reader (``heatcurv.io.las_header``).

The reader refuses a file whose header does not account for every byte or
does not describe its points. Real writers round bounding boxes, pad between
the VLRs and the points and leave bytes after a LAZ chunk table; this script
measures each rule on real files, so that a tolerance is a measured one:

- ``gap``: bytes between the last VLR and the points (zeros, the 0xDDCC
  signature, leftovers), and whether they hold VLRs the VLR count leaves out;
- ``record``: the record length against the point format's size plus the
  bytes the ExtraBytes VLRs describe;
- ``numbers``: scales, offsets and bounding box (finite, ordered, scales
  resolvable in double precision and finite over the int32 range);
- ``unexplained``: LAS, bytes after the points and after the extended VLRs;
  LAZ, the chunk table's byte counts against the compressed data, and the
  bytes after the chunk table (``+n``);
- ``box``: how far the farthest point lies outside the header's box, in
  scale steps (the reader allows 1; ``ints`` when the box is the records'
  unscaled integers, accepted);
- ``heatcurv``: what ``heatcurv.io.read_points`` does with the file.

Files are not shipped. The ones measured in docs/robustness.md: the
``tests/data`` of the laspy 2.7.0 sdist (``pip download --no-deps
--no-binary :all: laspy==2.7.0``) and ``test/data`` of a PDAL checkout.
Run ``python benchmarks/las_real_files.py DIR [DIR ...]`` (``--markdown``).
"""

from __future__ import annotations

import argparse
import struct
import sys
from collections import Counter
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from heatcurv.io import las_header as lh  # noqa: E402
from machine import commit, table  # noqa: E402  (benchmarks/machine.py)


class _Bytes:
    """The reader interface of ``las_header`` over bytes in memory."""

    def __init__(self, data: bytes):
        self.data, self.size = data, len(data)

    def read(self, position: int, count: int) -> bytes:
        return self.data[position:position + count]


def measure(path: Path) -> dict:
    """The quantity each rule looks at, for one file ("-" where the file is broken before it)."""
    import io

    import laspy
    import lazrs

    from heatcurv import HeatcurvError
    from heatcurv.io import read_points

    data = path.read_bytes()
    row = dict.fromkeys(("writer", "version", "points", "gap", "record", "numbers", "unexplained", "box"), "-")
    try:
        row["heatcurv"] = "read"
        read_points(path)
    except HeatcurvError as exc:
        row["heatcurv"] = str(exc).split(": ", 1)[1][:90]
    if data[:4] != b"LASF" or len(data) < 227 or data[24] != 1 or data[25] > 5:
        return row
    minor = data[25]
    header_size, offset, vlrs, raw_format, record_length, count = struct.unpack_from("<HIIBHI", data, 94)
    point_format, compressed = raw_format & 0x3F, bool(raw_format & 0x80)
    evlr_start = evlr_count = 0
    if minor >= 4:
        evlr_start, evlr_count, count = struct.unpack_from("<QIQ", data, 235)
    row["writer"] = data[58:90].split(b"\0")[0].decode("latin-1")[:24]
    row["version"] = f"1.{minor} f{point_format}{' laz' if compressed else ''}"
    row["points"] = str(count)
    reader = _Bytes(data)
    try:
        laszip, extra, end_of_vlrs = lh._walk_vlrs(reader, header_size, offset, vlrs)
    except lh.LasStructureError:
        return row
    hidden = lh._hidden_vlrs(reader, end_of_vlrs, offset)
    row["gap"] = f"{offset - end_of_vlrs}{' VLR!' if hidden else ''}"
    if point_format < len(lh._FORMAT_SIZE):
        described = lh._described_extra_bytes(extra)
        expected = lh._FORMAT_SIZE[point_format] + described
        row["record"] = "ok" if record_length == expected else f"{record_length} != {expected}"
    scales, offsets = struct.unpack_from("<3d", data, 131), struct.unpack_from("<3d", data, 155)
    hx, lx, hy, ly, hz, lz = struct.unpack_from("<6d", data, 179)
    box = ((lx, hx), (ly, hy), (lz, hz))
    try:
        lh._check_numbers(scales, offsets, box)
        row["numbers"] = "ok"
    except lh.LasStructureError as exc:
        row["numbers"] = str(exc)[:40]
    end = evlr_start if evlr_count else len(data)
    waveform = struct.unpack_from("<Q", data, 227)[0] if minor == 3 else 0
    if offset < waveform <= len(data):  # LAS 1.3: the waveform record after the points
        end = waveform
    if not compressed:
        row["unexplained"] = str(end - offset - count * record_length)
    elif laszip is not None:
        table_at = struct.unpack_from("<q", data, offset)[0]
        try:
            vlr = lazrs.LazVlr(laszip)
            stream = io.BytesIO(data)
            stream.seek(offset)
            entries = lazrs.read_chunk_table(stream, vlr)
            chunks = table_at - offset - 8 - sum(b for _p, b in entries)
            zipped = lh._LasZip(0, 0, (), laszip)
            spare = end - table_at - lh._chunk_table_length(data[table_at:end], zipped, entries)
            row["unexplained"] = f"{chunks} +{spare}"
        except BaseException as exc:  # lazrs errors, pyo3 panics
            row["unexplained"] = f"table: {type(exc).__name__}"
    if compressed and (laszip is None or struct.unpack_from("<H", laszip, 0)[0] not in (2, 3)):
        return row  # no compression lazrs reads
    try:
        las = laspy.read(path)
    except BaseException:  # noqa: BLE001 - laspy errors, lazrs panics: the file is broken before this rule
        return row
    if len(las.points):
        points = np.column_stack([las.x, las.y, las.z])
        low, high = np.array([b[0] for b in box]), np.array([b[1] for b in box])
        steps = np.maximum(points - high, low - points).max(axis=0) / np.abs(scales)
        row["box"] = f"{max(steps.max(), 0):.3g}"
        if steps.max() > 1:
            integers = (las.X, las.Y, las.Z)
            if all(np.all((v >= lo - 1) & (v <= hi + 1)) for v, (lo, hi) in zip(integers, box)):
                row["box"] += " ints"
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("directories", nargs="+", type=Path, help="directories searched for *.las and *.laz")
    parser.add_argument("--markdown", action="store_true", help="Markdown tables")
    args = parser.parse_args(argv)
    paths = sorted({p for d in args.directories for p in d.rglob("*") if p.suffix.lower() in (".las", ".laz")})
    columns = ["file", "writer", "version", "points", "gap", "record", "numbers", "unexplained", "box", "heatcurv"]
    rows = []
    for path in paths:
        row = measure(path)
        rows.append([path.name, *(row[c] for c in columns[1:])])
    print(f"heatcurv at commit {commit()}; {len(paths)} files\n")
    print(table("Each rule on each file", columns, rows, args.markdown))
    read = Counter(r[-1] == "read" for r in rows)
    print(f"read: {read[True]}, refused: {read[False]}")
    for k, name in enumerate(columns[4:9], start=4):
        print(f"{name}: " + ", ".join(f"{value} x{n}" for value, n in sorted(Counter(r[k] for r in rows).items())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
