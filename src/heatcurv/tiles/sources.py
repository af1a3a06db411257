"""Streaming readers for tiled runs: a cloud read a chunk at a time, never whole in one process.

=================  ===========================================================
format             how it is streamed
=================  ===========================================================
``.las`` ``.laz``  laspy's ``chunk_iterator``; passes that need only the
                   coordinates decode only XYZ (``DecompressionSelection.base()
                   | Z``: ``base()`` alone does not decode z)
``.ply``           binary (little or big endian): the ``vertex`` element,
                   one plain read per chunk; ASCII PLY is refused (convert it)
``.npy``           one plain read per chunk (the header parsed by
                   ``numpy.lib.format``): ``(n, >=3)`` (C or Fortran order) or
                   a structured array with ``x y z``
text, OBJ, OFF,    refused for tiling with a message that says what to do
NPZ
=================  ===========================================================

:class:`Source` gives the coordinates of rows ``[start, stop)`` as float64
(the values :func:`heatcurv.io.read_points` gives: LAS scaled and offset) and,
for the final write, the other per-point properties of those rows.

PLY and NPY are read, not memory-mapped: the pages of a map a pass has
walked through count as the driver's resident memory until it is unmapped
(a 100M-point NPY's stats pass measured 2.58 GB, the 2.4 GB file plus 0.2 GB),
while a read chunk is freed when the next one replaces it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import HeatcurvError

__all__ = ["Source", "open_source", "TILED_READ", "CHUNK_POINTS"]

#: Extensions a tiled run streams.
TILED_READ = (".las", ".laz", ".ply", ".npy")
#: Points per chunk of a streaming pass (about 24 MB of float64 coordinates).
CHUNK_POINTS = 1_000_000


def _refuse(path, problem: str) -> HeatcurvError:
    return HeatcurvError(f"cannot tile {path}: {problem}")


@dataclass
class Source:
    """A point-cloud file opened for streaming.

    Attributes
    ----------
    path : pathlib.Path
        The file.
    kind : {"las", "ply", "npy"}
        Its format family.
    count : int
        Number of points (rows).
    las_header : laspy.LasHeader or None
        LAS/LAZ: the header (point format, scales, offsets, VLRs).
    columns : list of str
        Names of the per-point properties other than the coordinates, in file
        order (LAS: the point format's dimensions without ``X Y Z``).
    meta : dict
        PLY: ``dtype``, ``offset`` (of the vertex data), ``header_size``,
        ``tail`` (byte range of the elements after the vertices), ``comments``,
        ``header_lines`` (of the other elements); NPY: ``dtype``, ``offset`` (of
        the data), ``fortran_order``, ``ncols`` (an ``(n, c)`` array) or ``xyz``
        (the coordinate fields of a structured array).
    """

    path: Path
    kind: str
    count: int
    las_header: object = None
    columns: list = field(default_factory=list)
    meta: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ coordinates
    def chunks(self, size: int = CHUNK_POINTS, *, coordinates_only: bool = True):
        """Yield ``(start, points, records)`` for consecutive row ranges of at most ``size`` rows.

        ``points`` is (k, 3) float64; ``records`` the raw rows (LAS: a laspy
        point record; PLY/NPY: the rows read), or None if ``coordinates_only``.
        """
        if self.kind == "las":
            import laspy

            from ..io.las_header import LasStructureError, check_points_in_box

            # base() alone leaves z undecoded: ask for Z too
            select = laspy.DecompressionSelection
            selection = select.base() | select.Z if coordinates_only else select.all()
            start = 0
            try:
                with laspy.open(self.path, decompression_selection=selection) as reader:
                    for record in reader.chunk_iterator(size):
                        k = len(record)
                        if k == 0:
                            break
                        points = np.empty((k, 3))
                        points[:, 0], points[:, 1], points[:, 2] = record.x, record.y, record.z
                        if "las_layout" in self.meta:
                            try:
                                check_points_in_box(self.meta["las_layout"], points, (record.X, record.Y, record.Z),
                                                    start)
                            except LasStructureError as exc:
                                raise HeatcurvError(f"cannot read {self.path}: {exc}") from None
                        yield start, points, None if coordinates_only else record
                        start += k
            except HeatcurvError:
                raise
            except (KeyboardInterrupt, SystemExit, GeneratorExit):
                raise
            except BaseException as exc:  # laspy / lazrs errors, pyo3 panics
                raise HeatcurvError(f"cannot read {self.path}: {type(exc).__name__}: {exc}") from None
            if start < self.count:
                raise HeatcurvError(f"cannot read {self.path}: truncated: the header announces {self.count} points, "
                                    f"the file holds {start}")
            return
        for start in range(0, self.count, size):
            rows = self._read(start, min(self.count, start + size))
            yield start, self._xyz(rows), None if coordinates_only else rows

    def _read(self, start: int, stop: int) -> np.ndarray:
        """Rows ``[start, stop)`` of a PLY's vertex element or an NPY array, read (not mapped)."""
        dtype, offset, count = self.meta["dtype"], self.meta["offset"], stop - start
        if self.meta.get("fortran_order"):
            # an (n, c) Fortran-order array stores its c columns one after the other
            n, ncols = self.count, self.meta["ncols"]
            rows = np.empty((count, ncols), dtype=dtype)
            for k in range(ncols):
                rows[:, k] = self._fromfile(dtype, count, offset + (k * n + start) * dtype.itemsize)
            return rows
        record = dtype.itemsize * self.meta.get("ncols", 1)
        rows = self._fromfile(dtype, count * self.meta.get("ncols", 1), offset + start * record)
        return rows.reshape(count, -1) if "ncols" in self.meta else rows

    def _fromfile(self, dtype, count: int, offset: int) -> np.ndarray:
        values = np.fromfile(self.path, dtype=dtype, count=count, offset=offset)
        if len(values) < count:
            raise HeatcurvError(f"cannot read {self.path}: truncated: the file ends {count - len(values)} values "
                                "before its header says")
        return values

    def _xyz(self, rows) -> np.ndarray:
        if self.kind == "npy" and rows.dtype.names is None:
            return np.array(rows[:, :3], dtype=np.float64)
        names = self.meta["xyz"]
        points = np.empty((len(rows), 3))
        for k, name in enumerate(names):
            points[:, k] = rows[name]
        return points

    # ------------------------------------------------------------------ other properties
    def properties(self, records) -> dict:
        """The per-point properties other than the coordinates of a chunk's ``records``, by name.

        Returns
        -------
        dict of str to ndarray, shape (k,)
            In native byte order; LAS array extra dimensions as ``name_0 name_1 ...``.
        """
        out = {}
        if self.kind == "las":
            for name in self.columns:
                values = np.asarray(records[name])
                if values.ndim == 2:
                    out.update({f"{name}_{k}": values[:, k] for k in range(values.shape[1])})
                else:
                    out[name] = values
            return out
        if self.kind == "npy" and records.dtype.names is None:
            return {name: np.asarray(records[:, k + 3]) for k, name in enumerate(self.columns)}
        for name in self.columns:
            values = np.asarray(records[name])
            out[name] = values.astype(values.dtype.newbyteorder("="))
        return out


def open_source(path) -> Source:
    """Open ``path`` for streaming (see the module's table).

    Raises
    ------
    HeatcurvError
        If the file is missing, empty, of a format that cannot be streamed (the
        message says what to convert it to), or its header is not valid.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if not path.is_file():
        raise HeatcurvError(f"cannot read {path}: no such file")
    if path.stat().st_size == 0:
        raise HeatcurvError(f"cannot read {path}: the file is empty")
    if ext not in TILED_READ:
        raise _refuse(path, f"{ext or 'a file without extension'} files are read whole; a tiled run streams "
                      f"{' '.join(TILED_READ)} (binary PLY): convert it first, or raise --max-memory to compute it "
                      "in memory")
    if ext in (".las", ".laz"):
        return _open_las(path)
    if ext == ".ply":
        return _open_ply(path)
    return _open_npy(path)


def _open_las(path: Path) -> Source:
    import laspy

    from ..io.las_header import LasStructureError, check_las_file

    try:
        layout = check_las_file(path)
    except LasStructureError as exc:
        raise HeatcurvError(f"cannot read {path}: {exc}") from None
    try:
        with laspy.open(path) as reader:
            header = reader.header
    except Exception as exc:
        raise HeatcurvError(f"cannot read {path}: not a valid LAS/LAZ file (laspy: {exc})") from None
    if header.point_count == 0:
        raise HeatcurvError(f"cannot read {path}: the file holds no points")
    columns = [name for name in header.point_format.dimension_names if name not in ("X", "Y", "Z")]
    return Source(path, "las", int(header.point_count), las_header=header, columns=columns,
                  meta={"las_layout": layout})


def _open_ply(path: Path) -> Source:
    import plyfile

    from ..io._common import _ROLE_OF, _canonical
    from ..io.ply import _ply_header

    size = path.stat().st_size
    header, header_size = _ply_header(path, size)
    if header.text:
        raise _refuse(path, "ASCII PLY is read whole; convert it to binary PLY or LAZ first, or raise --max-memory")
    offset, vertex, tail_start = header_size, None, None
    for element in header.elements:
        lists = any(isinstance(p, plyfile.PlyListProperty) for p in element.properties)
        if element.name == "vertex":
            if lists:
                raise _refuse(path, "its vertex element has list properties; a tiled run maps fixed-size vertices")
            vertex = element
            dtype = np.dtype([(p.name, p.dtype(header.byte_order)) for p in element.properties])
            tail_start = offset + element.count * dtype.itemsize
            break
        if lists:
            raise _refuse(path, f"the element {element.name!r} before the vertices has list properties")
        record = sum(np.dtype(p.dtype(header.byte_order)).itemsize for p in element.properties)
        offset += element.count * record
    if vertex is None:
        raise HeatcurvError(f"cannot read {path}: no 'vertex' element in the PLY file")
    if tail_start > size:
        raise HeatcurvError(f"cannot read {path}: truncated: the header announces {vertex.count} vertices of "
                            f"{dtype.itemsize} bytes, the file holds {size - offset} bytes after the header")
    roles = {}
    for name in dtype.names:
        role = _ROLE_OF.get(_canonical(name))
        if role in ("x", "y", "z") and role not in roles:
            roles[role] = name
    if len(roles) < 3:
        raise HeatcurvError(f"cannot read {path}: no x/y/z coordinate properties in its vertex element")
    xyz = [roles[a] for a in "xyz"]
    after = header.elements[header.elements.index(vertex) + 1:] if vertex in header.elements else []
    meta = {
        "dtype": dtype, "offset": offset, "xyz": xyz, "byte_order": header.byte_order,
        "tail": (tail_start, size) if after and header.byte_order in ("<", "=") else None,
        "tail_elements": list(after), "comments": list(header.comments), "obj_info": list(header.obj_info),
    }
    columns = [name for name in dtype.names if name not in xyz]
    return Source(path, "ply", int(vertex.count), columns=columns, meta=meta)


def _open_npy(path: Path) -> Source:
    try:
        array = np.load(path, mmap_mode="r")  # validates the header and the size; no data page is read
        # where the data starts and in which order: chunks are read from there, not through this map
        fortran_order = array.ndim == 2 and not array.flags.c_contiguous
        layout = {"dtype": array.dtype, "offset": int(array.offset), "fortran_order": fortran_order}
    except Exception as exc:
        raise HeatcurvError(f"cannot read {path}: not a valid NPY file ({exc})") from None
    if array.dtype.names:
        from ..io._common import _ROLE_OF, _canonical

        roles = {}
        for name in array.dtype.names:
            role = _ROLE_OF.get(_canonical(name))
            if role in ("x", "y", "z") and role not in roles:
                roles[role] = name
        if array.ndim != 1 or len(roles) < 3:
            raise HeatcurvError(f"cannot read {path}: a structured array must have shape (n,) and x y z fields")
        xyz = [roles[a] for a in "xyz"]
        columns = [name for name in array.dtype.names if name not in xyz and array[name].ndim == 1]
        return Source(path, "npy", int(array.shape[0]), columns=columns, meta={"xyz": xyz, **layout})
    if array.ndim != 2 or array.shape[1] < 3 or array.dtype.kind not in "iuf":
        raise HeatcurvError(f"cannot read {path}: expected an (n, >=3) array of numbers, got shape {array.shape} "
                            f"{array.dtype}")
    ncols = array.shape[1]
    names = ["nx", "ny", "nz"] if ncols == 6 else [f"column_{k}" for k in range(4, ncols + 1)]
    if array.shape[0] == 0:
        raise HeatcurvError(f"cannot read {path}: the file holds no points")
    layout["ncols"] = ncols
    return Source(path, "npy", int(array.shape[0]), columns=names, meta=layout)
