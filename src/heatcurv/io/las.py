"""LAS and LAZ: reading and writing with laspy (lazrs for LAZ), headers and extra dimensions kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import (
    _NORMAL_NAMES,
    _ROLE_OF,
    PointCloud,
    _canonical,
    _is_integral,
    _one_line,
    _Output,
    _read_error,
    _stored_dtype,
    _write_error,
)
from .atomic import raise_noted_stop, stop_signals_noted
from .las_header import LasLayout, LasStructureError, check_las_file, check_points_in_box

# LAS point formats without RGB -> the same format with RGB
_LAS_WITH_RGB = {0: 2, 1: 3, 2: 2, 3: 3, 4: 5, 5: 5, 6: 7, 7: 7, 8: 8, 9: 10, 10: 10}


def _laspy_problem(exc: BaseException, layout: LasLayout) -> str:
    """Plain words for what laspy or lazrs raised on a file that passed the structural checks."""
    message = _one_line(exc)
    kind = type(exc).__name__
    if isinstance(exc, MemoryError):
        need = layout.point_count * layout.record_length
        return (
            f"not enough memory to decode {layout.point_count} points of "
            f"{layout.record_length} bytes ({need / 1e6:.3g} MB)"
        )
    if "failed to fill whole buffer" in message:
        return (
            "the compressed point data ends before the points it announces: it is corrupt "
            f"or truncated (lazrs: {message})"
        )
    if message.startswith(("Item ", "Compressor type")):
        return f"the laszip VLR is corrupt or from an unsupported LASzip version (lazrs: {message})"
    if kind in ("LazrsError", "PanicException"):
        return f"the compressed point data is corrupt (lazrs: {message})"
    if "buffer size must be a multiple of element size" in message:
        return f"truncated inside the point records ({message})"
    if isinstance(exc, UnicodeDecodeError):
        return f"a text field of the header or of a VLR is not valid text ({message})"
    if isinstance(exc, OSError):
        return f"a position or size in the file is out of range ({message})"
    if message == kind or message.strip("-0123456789 ()'\"") == "":
        # a bare number or nothing: say what kind of error it was
        message = f"{kind} {message}" if message != kind else kind
    return f"not a valid LAS/LAZ file (laspy: {message})"


def _read_las(path: Path, fmt: str) -> PointCloud:
    try:
        layout = check_las_file(path)
    except LasStructureError as exc:
        raise _read_error(path, str(exc)) from None
    points, columns, extra_names, rgb16, header, integers = _decode_las(path, layout)
    if points.shape[0] < header.point_count:
        raise _read_error(
            path,
            f"truncated: the header announces {header.point_count} points, "
            f"the file holds {points.shape[0]}",
        )
    if points.shape[0] != header.point_count:
        raise _read_error(
            path, f"the header announces {header.point_count} points, {points.shape[0]} were decoded"
        )
    if points.shape[0] == 0:
        raise _read_error(path, "the file holds no points")
    try:
        check_points_in_box(layout, points, integers)
    except LasStructureError as exc:
        raise _read_error(path, str(exc)) from None
    normals = None
    role_of = {}
    for name in columns:
        role = _ROLE_OF.get(_canonical(name))
        if name in extra_names and role in _NORMAL_NAMES and role not in role_of:
            role_of[role] = name
    meta = {"las_header": header, "points_dtype": np.dtype(np.float64)}
    if all(role in role_of for role in _NORMAL_NAMES):
        stored = [columns.pop(role_of[role]) for role in _NORMAL_NAMES]
        meta["normals_dtype"] = _stored_dtype(stored)
        normals = np.column_stack([values.astype(np.float64) for values in stored])
    colours = None
    if rgb16 is not None:
        colours = (
            rgb16.astype(np.uint8)
            if rgb16.max(initial=0) <= 255
            else np.round(rgb16 / 257.0).astype(np.uint8)
        )
        meta["las_rgb16"] = rgb16
        if not np.array_equal(colours, rgb16):
            meta["colour_values"] = rgb16
    return PointCloud(
        points=np.ascontiguousarray(points),
        normals=normals,
        colours=colours,
        fields=columns,
        path=path,
        format=fmt,
        meta=meta,
    )


def _decode_las(path: Path, layout) -> tuple:
    """laspy's decoding of a checked file: ``(points, columns, extra_names, rgb16, header, integers)``.

    ``points`` are the scaled coordinates (float64, shape (n, 3)); ``columns`` every other dimension but the
    colours (an array extra dimension split into one field per element); ``extra_names`` the extra
    dimensions' names; ``rgb16`` the colours as stored (uint16, shape (n, 3)) or None; ``integers`` the
    record integers ``X, Y, Z``. laspy's and the LAZ decoder's failures are a one-line error.
    """
    import errno

    import laspy

    try:
        # a huge fixed chunk size: the parallel decoder would allocate a whole chunk
        backend = laspy.LazBackend.Lazrs if layout.sequential else None
        las = laspy.read(path, laz_backend=backend)
        points = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)]).astype(
            np.float64
        )
        dimension_names = list(las.point_format.dimension_names)
        extra_names = set(las.point_format.extra_dimension_names)
        columns = {}
        for name in dimension_names:
            if name in ("X", "Y", "Z", "red", "green", "blue"):
                continue
            values = np.array(las[name])
            if values.ndim == 2:  # array extra bytes ("3f8"): one field per element
                for k in range(values.shape[1]):
                    columns[f"{name}_{k}"] = values[:, k].copy()
            else:
                columns[name] = values
        rgb16 = None
        if "red" in dimension_names:
            rgb16 = np.column_stack(
                [np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)]
            ).astype(np.uint16)
        return points, columns, extra_names, rgb16, las.header, (las.X, las.Y, las.Z)
    except OSError as exc:
        if exc.errno not in (errno.EINVAL, errno.EOVERFLOW, None):
            raise  # the disk or the permissions, not the file's content
        raise _read_error(path, _laspy_problem(exc, layout)) from None
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as exc:  # laspy / lazrs errors, pyo3 panics (not Exceptions)
        raise _read_error(path, _laspy_problem(exc, layout)) from None


def _las_scales_offsets(points: np.ndarray):
    """Power-of-ten scale at most 1e-6 of the largest bounding-box side, round offsets.

    Returns
    -------
    scales, offsets : ndarray, shape (3,)
    """
    if points.shape[0] == 0:
        return np.full(3, 1e-3), np.zeros(3)
    low, high = points.min(axis=0), points.max(axis=0)
    extent = float(np.max(high - low))
    if not extent > 0:
        extent = max(1.0, float(np.abs(low).max()) * 1e-3)
    exponent = int(np.floor(np.log10(extent * 1e-6)))
    scale = 10.0**exponent
    unit = 10.0 ** (exponent + 6)  # a round number no larger than the extent
    offsets = np.floor(low / unit) * unit
    return np.full(3, scale), offsets


def _fits_exactly(values: np.ndarray, dtype: np.dtype) -> bool:
    """Whether ``values`` converts to ``dtype`` without changing any value."""
    if dtype.kind == "f":
        return True
    if values.dtype.kind == "f" and not _is_integral(values):
        return False
    if values.size == 0:
        return True
    info = np.iinfo(dtype)
    return info.min <= values.min() and values.max() <= info.max


def _extra_dimensions(laspy, extra: dict, output: _Output, source_header):
    """The extra-bytes dimensions to add for the columns ``extra``, and the values to set.

    A source LAS property written back unchanged keeps its definition (type,
    scale and offset, description), and the components ``name_0``,
    ``name_1``... of an array dimension become that array dimension again.

    Returns
    -------
    params : list of laspy.ExtraBytesParams
    values : dict of str to ndarray, shape (n,) or (n, k)
    """
    definitions = {}
    if source_header is not None:
        definitions = {dim.name: dim for dim in source_header.point_format.extra_dimensions}
    kept = output.source_names
    params, values = [], {}
    for name, column in extra.items():
        if name in values:
            continue
        dim = definitions.get(name) if name in kept else None
        base, _, index = name.rpartition("_")
        array_dim = definitions.get(base) if name in kept and index.isdigit() else None
        if dim is not None and dim.num_elements == 1:
            params.append(
                laspy.ExtraBytesParams(
                    name=name, type=dim.dtype, description=dim.description,
                    scales=dim.scales, offsets=dim.offsets,
                )
            )
            values[name] = column
            continue
        if array_dim is not None and array_dim.num_elements > 1 and base not in values and base not in extra:
            parts = [f"{base}_{k}" for k in range(array_dim.num_elements)]
            if all(part in kept and part in extra for part in parts):
                params.append(
                    laspy.ExtraBytesParams(
                        name=base, type=array_dim.dtype, description=array_dim.description,
                        scales=array_dim.scales, offsets=array_dim.offsets,
                    )
                )
                values[base] = np.column_stack([extra[part] for part in parts])
                values.update({part: None for part in parts})  # written as part of the array
                continue
        dtype = column.dtype
        if dtype.kind == "b":
            dtype = np.dtype(np.uint8)
        elif dtype.kind == "f" and dtype.itemsize < 4:
            dtype = np.dtype(np.float32)
        params.append(laspy.ExtraBytesParams(name=name, type=dtype))
        values[name] = column
    return params, {name: column for name, column in values.items() if column is not None}


def _output_header(laspy, output: _Output, source_header):
    """The header to write: the source's (its extra dimensions dropped, a point format with colours if they
    are added), or a LAS 1.4 header of point format 6 or 7 with scales and offsets fitted to the points."""
    import datetime

    if source_header is not None:
        header = source_header.copy()
        header.remove_extra_dims(list(header.point_format.extra_dimension_names))
        if output.colours is not None and "red" not in header.point_format.dimension_names:
            target = _LAS_WITH_RGB[header.point_format.id]
            version = str(header.version)
            if target == 5 and version < "1.3" or target in (7, 8, 10) and version < "1.4":
                version = "1.4"
            header.set_version_and_point_format(
                laspy.header.Version.from_str(version), laspy.PointFormat(target)
            )
        header.partial_reset()
        header.creation_date = datetime.date.today()
    else:
        header = laspy.LasHeader(point_format=7 if output.colours is not None else 6, version="1.4")
        header.scales, header.offsets = _las_scales_offsets(output.points)
    header.generating_software = "heatcurv"
    return header


def _colours16(output: _Output) -> np.ndarray:
    """The colours as LAS stores them, uint16 of shape (n, 3): the source's 16-bit values where they are the
    source's, else the 8-bit colours times 257."""
    rgb16 = output.source.meta.get("las_rgb16") if output.colours_from_source else None
    stored = output.colour_values
    if rgb16 is None and stored is not None and stored.dtype == np.uint16:
        rgb16 = stored  # 16-bit colours of a PLY source
    if rgb16 is None:
        rgb16 = output.colours.astype(np.uint16) * np.uint16(257)
    return rgb16


def _write_las(stream, output: _Output, path: Path) -> None:
    import laspy

    points = output.points
    finite = np.isfinite(points).all(axis=1)
    if not finite.all():
        rows = np.flatnonzero(~finite)
        raise _write_error(
            path,
            "LAS cannot store NaN or infinite coordinates "
            f"({rows.size} row(s), first row {rows[0]})",
        )
    n = points.shape[0]
    source_header = output.source.meta.get("las_header") if output.source is not None else None
    header = _output_header(laspy, output, source_header)
    standard = set(header.point_format.dimension_names)
    extra = dict(output.columns)
    if output.normals is not None:
        extra = {**{name: output.normals[:, k] for k, name in enumerate(_NORMAL_NAMES)}, **extra}
    fill_standard = {}
    for name in list(extra):
        if name in standard:
            # a standard dimension gets the values as given (not narrowed: gps_time is double)
            values = extra.pop(name)
            fill_standard[name] = output.uncast.get(name, values)
        elif len(name.encode("utf-8")) > 32:
            raise _write_error(path, f"field name {name!r} is longer than the 32 bytes LAS allows")
    params, extra = _extra_dimensions(laspy, extra, output, source_header)
    try:
        if params:
            header.add_extra_dims(params)
        las = laspy.LasData(
            header=header, points=laspy.ScaleAwarePointRecord.zeros(n, header=header)
        )
        las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    except OverflowError:
        raise _write_error(
            path,
            f"the coordinates do not fit the LAS scales {header.scales} "
            f"and offsets {header.offsets}",
        ) from None
    except Exception as exc:
        raise _write_error(path, f"laspy: {_one_line(exc)}") from None

    if output.colours is not None:
        rgb16 = _colours16(output)
        las.red, las.green, las.blue = rgb16[:, 0], rgb16[:, 1], rgb16[:, 2]
    for name, values in fill_standard.items():
        target = np.asarray(las[name]).dtype
        if not _fits_exactly(values, target):
            raise _write_error(
                path, f"field {name!r} does not fit the LAS dimension {name} ({target})"
            )
        try:
            las[name] = values.astype(target)
        except (OverflowError, ValueError) as exc:
            raise _write_error(
                path, f"field {name!r} does not fit the LAS dimension {name} ({_one_line(exc)})"
            ) from None
    for name, values in extra.items():
        las[name] = values.astype(np.uint8) if values.dtype.kind == "b" else values
    failure = None
    with stop_signals_noted() as arrived:
        try:
            las.write(stream, do_compress=path.suffix.lower() == ".laz")
        except Exception as exc:
            failure = exc
    raise_noted_stop(arrived)  # lazrs reports Ctrl-C or SIGTERM during its writes as a failed write
    if failure is not None:
        raise _write_error(path, f"laspy: {_one_line(failure)}") from None
