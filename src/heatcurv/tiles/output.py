"""Results of a tiled run: an index-addressed scratch file, then the output written in input order.

Each finished tile's core rows are appended to the bucket files of their input
rows (:func:`store_tile`: sequential writes, whatever the input's order); once
every tile is in, :func:`merge_buckets` puts each bucket into ``results.rec``
(one record of :data:`RECORD` per input row). The final pass reads ``results.rec`` and the input together,
a chunk of rows at a time and in input order, applies the orientation flips
(:mod:`.orient`), and writes the output through
:func:`heatcurv.io.atomic.atomic_write`: there is never a partial output file.

Output formats
--------------
``.las`` ``.laz``
    From a LAS/LAZ input: every input dimension and the raw integer
    coordinates, unchanged (point format, scales, offsets, VLRs and CRS kept),
    plus the results as extra dimensions (float32, or float64 with
    ``dtype="float64"``; masks uint8, ``neighbours`` int32). From PLY or NPY:
    LAS 1.4 point format 6 with the scales of :func:`heatcurv.io.write_points`
    and the input's properties as extra dimensions. The run's parameters are a
    VLR (user id ``heatcurv``, record id 13) holding JSON.
``.ply``
    Binary little endian: ``x y z`` (as stored in a PLY input, else double),
    the input's other properties, the results; the elements after the
    vertices of a little-endian PLY input (faces) are copied; a ``comment
    heatcurv-tiles {...}`` line holds the run's parameters.

Field names are those of ``heatcurv compute`` (:mod:`heatcurv.cli.fields`):
``nx ny nz mean gaussian k1 k2 d1x d1y d1z d2x d2y d2z area reliable`` by
default; ``border outlier spacing neighbours fit_radius`` on request.
"""

from __future__ import annotations

import json
import os
import shutil

import numpy as np

from ..errors import HeatcurvError
from .compute import RESULT_FIELDS
from .sources import CHUNK_POINTS, Source

__all__ = [
    "RECORD", "DEFAULT_FIELDS", "EXTRA_FIELDS", "ERROR_FIELDS", "TILED_FIELDS", "TILED_WRITE", "create_results",
    "chunk_flips", "keyed_flips", "store_tile", "prepare_buckets", "merge_buckets", "write_records",
    "read_results", "output_columns", "write_output",
]

#: One record per input row of ``results.rec``: every result field, the seam and winding patch keys
#: (:mod:`.orient`, :mod:`.winding`), the row's weight and normal in its object's outward vote (the frame's unit,
#: the tile's orientation's normal before the fit refines it; 0 unless oriented ``outward``), whether it was computed.
RECORD = np.dtype(
    [(name, "u1" if dt is np.bool_ else np.dtype(dt).str, (cols,)) if cols > 1
     else (name, "u1" if dt is np.bool_ else np.dtype(dt).str) for name, (cols, dt) in RESULT_FIELDS.items()]
    + [("patch", "<i8"), ("winding", "<i8"), ("winding_fine", "<i8"), ("vote_weight", "<f8"),
       ("vote_normal", "<f4", (3,)), ("computed", "u1")]
)
#: The fields written by default, in the order of ``heatcurv compute`` (heatcurv.cli.fields.DEFAULT_FIELDS).
DEFAULT_FIELDS = (
    "nx", "ny", "nz", "mean", "gaussian", "k1", "k2",
    "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area", "reliable",
)
#: Further fields a tiled run can write (heatcurv.cli.fields.EXTRA_FIELDS).
EXTRA_FIELDS = ("border", "outlier", "spacing", "neighbours", "fit_radius")
#: The standard errors (heatcurv.cli.fields.ERROR_FIELDS), computed where they are asked for.
ERROR_FIELDS = ("mean_se", "gaussian_se", "k1_se", "k2_se", "normal_se")
#: Every field a tiled run writes, in the written order (the features are not computed in tiles).
TILED_FIELDS = DEFAULT_FIELDS + EXTRA_FIELDS + ERROR_FIELDS
#: Output extensions of a tiled run.
TILED_WRITE = (".las", ".laz", ".ply")
#: Patch key of a tile's patch: ``tile << PATCH_SHIFT | label``.
PATCH_SHIFT = 32

_PLY_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint",
              "f4": "float", "f8": "double"}


def create_results(path, count: int, *, keep: bool = False) -> bool:
    """An all-zero ``results.rec`` of ``count`` records (a sparse file); return whether it was kept.

    With ``keep``, an existing file of exactly that size is kept as it is (a
    resumed run: it holds the rows of the tiles already stored).
    """
    if keep and os.path.exists(path) and os.path.getsize(path) == count * RECORD.itemsize:
        return True
    with open(path, "wb") as stream:
        stream.truncate(count * RECORD.itemsize)
    return False


#: What a tile's result file keeps once its rows are stored (:func:`store_tile`): the seam vote's inputs
#: (:func:`heatcurv.tiles.orient.seam_flips`) and the ``stored`` mark. The per-point fields, about
#: 170 bytes a core point, would double the scratch (at 100M points 17 of 39 GB).
STORED_KEYS = ("moment_labels", "moments", "halo_rows", "halo_normals", "halo_patch", "sheet_rows", "sheet_columns")
#: What a tile oriented ``outward`` keeps for the winding step (:func:`heatcurv.tiles.winding.tile_sources`).
SOURCE_KEYS = ("winding_rows", "winding_x", "winding_normals", "winding_area", "winding_label", "winding_fine_label",
               "winding_seam", "winding_roundness", "winding_total")


def is_stored(tile_file) -> bool:
    """Whether ``tile_file``'s rows are already in the buckets (the file was slimmed by :func:`slim_tiles`)."""
    with np.load(tile_file) as data:
        return "stored" in data.files


#: Input rows per bucket file (:func:`store_tile`): a bucket's span of ``results.rec`` is about 130 MB.
BUCKET_ROWS = 1 << 19
#: A stored row in a bucket file: its input row and its record.
BUCKET_RECORD = np.dtype([("row", "<i8"), ("record", RECORD)])


def bucket_path(buckets, bucket: int) -> str:
    """The file of ``bucket`` (input rows ``[bucket * BUCKET_ROWS, (bucket + 1) * BUCKET_ROWS)``) in ``buckets``."""
    return os.path.join(buckets, f"bucket_{bucket:07d}.rec")


def store_tile(buckets, tile_file, tile: int) -> int:
    """Append a finished tile's core rows to the bucket files of their input rows; return the row count.

    A tile's rows are spread over the whole input (in any order a file may
    have). Written at their rows into ``results.rec`` they would touch a large
    share of its pages, which are read back from disk once the file outgrows
    the page cache; appended to the bucket of :data:`BUCKET_ROWS` input rows each falls in,
    they are written sequentially, and :func:`merge_buckets` puts every bucket
    into place once. The appends go through the page cache, not flushed: the
    driver's loop does not wait for the disk. :func:`slim_tiles` makes them durable.
    """
    with np.load(tile_file) as data:
        rows = data["rows"]
        bucket = rows // BUCKET_ROWS
        order = np.argsort(bucket, kind="stable")  # each column gathered into bucket order as it is copied
        bucket = bucket[order]
        block = np.empty(len(rows), dtype=BUCKET_RECORD)
        block["row"] = rows[order]
        record = block["record"]
        for name in RESULT_FIELDS:
            record[name] = data[name][order]
        for key in ("patch", "winding", "winding_fine"):  # the tile's labels, made the cloud's keys
            record[key] = (np.int64(tile) << PATCH_SHIFT) | data[key][order]
        record["vote_weight"], record["vote_normal"] = data["vote_weight"][order], data["vote_normal"][order]
        record["computed"] = 1
    cuts = np.flatnonzero(np.diff(bucket)) + 1
    for lo, hi in zip([0, *cuts.tolist()], [*cuts.tolist(), len(block)]):
        with open(bucket_path(buckets, int(bucket[lo])), "ab") as stream:
            block[lo:hi].tofile(stream)
    return len(rows)


def prepare_buckets(buckets, keep: bool) -> None:
    """Create the bucket directory, emptied unless ``keep`` (a resume).

    A kept bucket is cut back to whole records: a crash mid-append may have
    left part of one, which would shift every record appended after it.
    """
    if not keep:
        shutil.rmtree(buckets, ignore_errors=True)
    os.makedirs(buckets, exist_ok=True)
    for name in os.listdir(buckets):
        bucket_file = os.path.join(buckets, name)
        size = os.path.getsize(bucket_file)
        if size % BUCKET_RECORD.itemsize:
            os.truncate(bucket_file, size - size % BUCKET_RECORD.itemsize)


def merge_buckets(path, buckets) -> None:
    """Put every bucket's rows into ``results.rec`` at their input rows, one bucket at a time, and delete it.

    A bucket's span of ``results.rec`` is read, overlaid with the bucket's rows
    (a row stored twice, by a tile computed again after a resume, has the same
    record both times) and written back in one sequential write, made durable
    before the bucket file is deleted: a merge cut short resumes from the
    buckets left.
    """
    count = os.path.getsize(path) // RECORD.itemsize
    for first in range(0, count, BUCKET_ROWS):
        bucket_file = bucket_path(buckets, first // BUCKET_ROWS)
        if not os.path.exists(bucket_file):
            continue
        stored = np.fromfile(bucket_file, dtype=BUCKET_RECORD)
        span = read_results(path, first, min(count, first + BUCKET_ROWS))
        span[stored["row"] - first] = stored["record"]
        with open(path, "r+b") as stream:
            stream.seek(first * RECORD.itemsize)
            span.tofile(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.unlink(bucket_file)


def slim_tiles(buckets, tile_files) -> None:
    """Make the bucket files durable (fsync), then slim each stored tile file to :data:`STORED_KEYS`.

    Each file is replaced atomically by its seam-vote inputs and a ``stored``
    mark: a resumed run finds its rows in the kept buckets (or in
    ``results.rec``, once merged). A file not slimmed yet still holds its rows
    and is stored again on resume.
    """
    if not tile_files:
        return
    for name in os.listdir(buckets):
        descriptor = os.open(os.path.join(buckets, name), os.O_RDONLY)
        try:
            os.fsync(descriptor)
        finally:
            os.close(descriptor)
    for tile_file in tile_files:
        with np.load(tile_file) as data:
            if "stored" in data.files:
                continue
            kept = {name: data[name] for name in STORED_KEYS + SOURCE_KEYS if name in data.files}
            count = np.int64(len(data["rows"]))
        temporary = f"{tile_file}.{os.getpid()}.tmp.npz"
        try:
            np.savez(temporary, stored=count, **kept)
            os.replace(temporary, tile_file)
        except BaseException:
            if os.path.exists(temporary):
                os.unlink(temporary)
            raise


#: Records of ``results.rec`` mapped at once when rows are written or rewritten (about 200 MB).
WINDOW_ROWS = 1 << 20


def write_records(path, records: np.ndarray, rows: np.ndarray) -> None:
    """Write ``records`` at the increasing ``rows`` of ``results.rec``, mapping only the rows' span."""
    if not len(rows):
        return
    first, last = int(rows[0]), int(rows[-1]) + 1
    span = np.memmap(path, dtype=RECORD, mode="r+", offset=first * RECORD.itemsize, shape=(last - first,))
    try:
        span[rows - first] = records  # unmapped below; the kernel writes the pages back (slim_tiles: fsync)
    finally:
        del span


def gather_records(path, rows: np.ndarray) -> np.ndarray:
    """Records of ``results.rec`` at the increasing ``rows``, one window of the file mapped at a time.

    A whole-file map would keep every page it touched resident (at 100M points
    the halo rows of 512 tiles touch most of a 10 GB file).
    """
    out = np.empty(len(rows), dtype=RECORD)
    for window in np.unique(rows // WINDOW_ROWS).tolist():
        lo, hi = np.searchsorted(rows, [window * WINDOW_ROWS, (window + 1) * WINDOW_ROWS])
        first, last = int(rows[lo]), int(rows[hi - 1]) + 1
        span = np.memmap(path, dtype=RECORD, mode="r", offset=first * RECORD.itemsize, shape=(last - first,))
        try:
            out[lo:hi] = span[rows[lo:hi] - first]
        finally:
            del span
    return out


def read_results(path, start: int, stop: int) -> np.ndarray:
    """Records of input rows ``[start, stop)`` (a plain read: no map stays in memory)."""
    return np.fromfile(path, dtype=RECORD, count=stop - start, offset=start * RECORD.itemsize)


def _flipped(block: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """The records seen from the other side where ``flip``: heatcurv.fits.principal.PrincipalCurvatures.flipped."""
    from ..fits.principal import PrincipalCurvatures

    if not flip.any():
        return block
    pc = PrincipalCurvatures(k1=block["k1"], k2=block["k2"], d1=block["d1"], d2=block["d2"], mean=block["mean"],
                             gaussian=block["gaussian"], well_posed=np.ones(len(block), bool)).flipped(flip)
    block = block.copy()
    for name in ("k1", "k2", "d1", "d2", "mean", "gaussian"):
        block[name] = getattr(pc, name)
    block["normals"] = np.where(flip[:, None], -block["normals"], block["normals"])
    # k1 and k2 trade places on the other side, and so do their standard errors
    k1_se = block["k1_se"].copy()
    block["k1_se"] = np.where(flip, block["k2_se"], block["k1_se"])
    block["k2_se"] = np.where(flip, k1_se, block["k2_se"])
    return block


def output_columns(block: np.ndarray, wanted, dtype) -> dict:
    """The written fields of a chunk of records, by written name (rows not computed: NaN, or 0 in masks)."""
    missing = block["computed"] == 0
    out = {}
    for name in TILED_FIELDS:
        if name not in wanted:
            continue
        if name in ("nx", "ny", "nz"):
            values = block["normals"][:, "xyz".index(name[1])]
        elif name[:2] in ("d1", "d2") and len(name) == 3:
            values = block[name[:2]][:, "xyz".index(name[2])]
        else:
            values = block[name]
        kind = RESULT_FIELDS.get(name, (1, np.float64))[1] if name in RESULT_FIELDS else np.float64
        if kind is np.bool_:
            values = values.astype(np.uint8)
        elif kind is np.int64:
            values = values.astype(np.int32)
        else:
            values = values.astype(dtype)
            if missing.any():
                values[missing] = np.nan
        out[name] = values
    return out


def keyed_flips(key: np.ndarray, keys: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """Whether each ``key`` is among the sorted ``keys`` with ``flip`` set, shape (len(key),), bool."""
    if len(keys) == 0:
        return np.zeros(len(key), dtype=bool)
    at = np.clip(np.searchsorted(keys, key), 0, len(keys) - 1)
    return (keys[at] == key) & flip[at]


def chunk_flips(block: np.ndarray, start: int, flips, rows: np.ndarray | None = None) -> np.ndarray:
    """Whether each record of a chunk is turned over: an odd number of ``flips`` say so, shape (len(block),), bool.

    ``flips``: ``(column, keys, flipped)`` triples (the seam flips by ``patch``,
    the winding step's by ``winding`` and ``winding_fine``, single rows by
    ``row``: the input row numbers), or None. ``start``: the chunk's first row;
    ``rows``: instead, the records' input rows (records gathered from anywhere).
    """
    flip = np.zeros(len(block), dtype=bool)
    if rows is None:
        rows = np.arange(start, start + len(block), dtype=np.int64)
    for column, keys, flipped in flips or ():
        key = rows if column == "row" else block[column]
        flip ^= keyed_flips(key, keys, flipped)
    return flip & (block["computed"] == 1)


def _results_chunks(results_path, count: int, flips, size: int = CHUNK_POINTS):
    """``(start, records)`` in input order, each record turned over where :func:`chunk_flips` says so."""
    for start in range(0, count, size):
        stop = min(count, start + size)
        block = read_results(results_path, start, stop)
        yield start, _flipped(block, chunk_flips(block, start, flips))


def write_output(stream, dst, source: Source, stats, results_path, wanted, dtype, flips, parameters: dict) -> None:
    """Write the output file to ``stream`` (see the module's table), a chunk of rows at a time, input order."""
    ext = os.path.splitext(str(dst))[1].lower()
    chunks = _results_chunks(results_path, source.count, flips)
    if ext in (".las", ".laz"):
        _write_las(stream, ext == ".laz", source, stats, chunks, wanted, np.dtype(dtype), parameters)
    elif ext == ".ply":
        _write_ply(stream, source, chunks, wanted, np.dtype(dtype), parameters)
    else:
        raise HeatcurvError(f"cannot write {dst}: a tiled run writes {' '.join(TILED_WRITE)}")


def _las_header(laspy, source: Source, stats, wanted, dtype, parameters):
    from ..io.las import _las_scales_offsets

    computed = [n for n in TILED_FIELDS if n in wanted]
    if source.las_header is not None:
        header = source.las_header.copy()
        clash = [n for n in header.point_format.extra_dimension_names if n in computed]
        if clash:
            header.remove_extra_dims(clash)
        header.partial_reset()
        carried = []
    else:
        header = laspy.LasHeader(point_format=6, version="1.4")
        corners = np.array([stats.low, stats.high])
        header.scales, header.offsets = _las_scales_offsets(corners)
        standard = set(header.point_format.dimension_names)
        carried = [n for n in source.columns if n not in computed and n not in standard and len(n.encode()) <= 32]
    header.generating_software = "heatcurv"
    params = []
    sample = next(source.chunks(1, coordinates_only=False))[2] if carried else None
    for name in carried:
        values = np.asarray(source.properties(sample)[name])
        params.append(laspy.ExtraBytesParams(name=name, type=np.uint8 if values.dtype.kind == "b" else values.dtype))
    for name in computed:
        kind = RESULT_FIELDS.get(name, (1, np.float64))[1]
        stored = np.uint8 if kind is np.bool_ else np.int32 if kind is np.int64 else dtype
        params.append(laspy.ExtraBytesParams(name=name, type=np.dtype(stored)))
    header.add_extra_dims(params)
    header.vlrs = [v for v in header.vlrs if getattr(v, "user_id", "") != "heatcurv"]
    header.vlrs.append(laspy.VLR(user_id="heatcurv", record_id=13, description="tiled run parameters",
                                 record_data=json.dumps(parameters, sort_keys=True, default=repr).encode()))
    return header, carried


def _write_las(stream, compress, source, stats, chunks, wanted, dtype, parameters):
    import laspy

    header, carried = _las_header(laspy, source, stats, wanted, dtype, parameters)
    # lazrs compresses the chunks on every core (the same bytes as its sequential writer)
    backend = laspy.LazBackend.LazrsParallel if compress else None
    with laspy.open(stream, mode="w", header=header, do_compress=compress, closefd=False,
                    laz_backend=backend) as writer:
        reader = source.chunks(CHUNK_POINTS, coordinates_only=False)
        for (_, points, records), (_, block) in zip(reader, chunks):
            record = laspy.ScaleAwarePointRecord.zeros(len(points), header=header)
            if source.kind == "las":
                record.copy_fields_from(records)
            else:
                record.x, record.y, record.z = points[:, 0], points[:, 1], points[:, 2]
                properties = source.properties(records)
                for name in carried:
                    record[name] = properties[name]
            for name, values in output_columns(block, wanted, dtype).items():
                record[name] = values
            writer.write_points(record)


def _write_ply(stream, source, chunks, wanted, dtype, parameters):
    computed = [n for n in TILED_FIELDS if n in wanted]
    xyz_dtype = np.dtype(np.float64)
    if source.kind == "ply":
        stored = source.meta["dtype"]
        kinds = {stored[name].kind + str(stored[name].itemsize) for name in source.meta["xyz"]}
        xyz_dtype = np.dtype("<f4") if kinds == {"f4"} else xyz_dtype
    sample = next(source.chunks(1, coordinates_only=False))[2]
    props = {n: v for n, v in source.properties(sample).items() if n not in computed}
    layout = [(a, xyz_dtype.newbyteorder("<")) for a in "xyz"]
    for name, values in props.items():
        kind = values.dtype
        if kind.kind == "b":
            kind = np.dtype("u1")
        elif kind.itemsize == 8 and kind.kind in "iu":
            kind = np.dtype("f8")  # PLY has no 64-bit integers
        layout.append((name, kind.newbyteorder("<")))
    for name in computed:
        kind = RESULT_FIELDS.get(name, (1, np.float64))[1]
        layout.append((name, np.dtype("u1" if kind is np.bool_ else "<i4" if kind is np.int64 else dtype)
                       .newbyteorder("<")))
    record = np.dtype(layout)
    tail_header = ""
    if source.kind == "ply" and source.meta.get("tail"):
        tail_header = "".join(element.header + "\n" for element in source.meta["tail_elements"])
    comments = [c for c in source.meta.get("comments", []) if not c.startswith("heatcurv-tiles ")]
    lines = ["ply", "format binary_little_endian 1.0"]
    lines += [f"comment {c}" for c in comments]
    lines.append("comment heatcurv-tiles " + json.dumps(parameters, sort_keys=True, default=repr))
    lines += [f"obj_info {c}" for c in source.meta.get("obj_info", [])]
    lines.append(f"element vertex {source.count}")
    lines += [f"property {_PLY_NAMES[record[name].kind + str(record[name].itemsize)]} {name}" for name in record.names]
    stream.write(("\n".join(lines) + "\n" + tail_header + "end_header\n").encode("ascii"))
    reader = source.chunks(CHUNK_POINTS, coordinates_only=False)
    for (_, points, records), (_, block) in zip(reader, chunks):
        rows = np.empty(len(points), dtype=record)
        for k, axis in enumerate("xyz"):
            rows[axis] = records[source.meta["xyz"][k]] if source.kind == "ply" else points[:, k]
        properties = source.properties(records)
        for name in props:
            rows[name] = properties[name]
        for name, values in output_columns(block, wanted, dtype).items():
            rows[name] = values
        stream.write(rows.tobytes())
    if source.kind == "ply" and source.meta.get("tail"):
        begin, end = source.meta["tail"]
        with open(source.path, "rb") as raw:
            raw.seek(begin)
            while begin < end:
                data = raw.read(min(1 << 24, end - begin))
                if not data:
                    break
                stream.write(data)
                begin += len(data)
