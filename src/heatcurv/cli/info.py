"""``heatcurv info INPUT``: points, bounding box, spacing and the fields of a point-cloud file."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .console import EXIT_OK, Log
from .steps import read_cloud

__all__ = ["run", "describe_spacing"]


def _ply_encoding(path: Path) -> str | None:
    """``ascii``, ``binary_little_endian`` or ``binary_big_endian`` from a PLY header."""
    try:
        with open(path, "rb") as stream:
            head = stream.read(4096).decode("latin-1")
    except OSError:
        return None
    match = re.search(r"^format\s+(\S+)", head, flags=re.MULTILINE)
    return match[1] if match else None


def _human_bytes(size: int) -> str:
    """A file size in bytes, kB, MB or GB."""
    for unit in ("bytes", "kB", "MB", "GB"):
        if size < 1000 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "bytes" else f"{size:.1f} {unit}"
        size /= 1000.0
    return f"{size} bytes"  # pragma: no cover


def describe_spacing(points: np.ndarray, *, max_queries: int = 200_000, seed: int = 0) -> dict:
    """Median distances to the nearest and the 8th nearest neighbour (distinct points).

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Finite coordinates.
    max_queries : int, optional
        Above this many points, the medians are taken over a random subset of
        query points (the tree holds every point).
    seed : int, optional
        Seed of that subset.

    Returns
    -------
    dict
        ``nearest`` and ``eighth`` (NaN with too few points) and ``queried``
        (points the medians are over).
    """
    from scipy.spatial import cKDTree

    n = points.shape[0]
    if n < 2:
        return {"nearest": float("nan"), "eighth": float("nan"), "queried": 0}
    tree = cKDTree(points)
    query = points
    if n > max_queries:
        query = points[np.random.default_rng(seed).choice(n, max_queries, replace=False)]
    k = min(9, n)
    distance, _ = tree.query(query, k=k, workers=-1)
    return {
        "nearest": float(np.median(distance[:, 1])),
        "eighth": float(np.median(distance[:, 8])) if k == 9 else float("nan"),
        "queried": int(query.shape[0]),
    }


def _file_line(cloud, path: Path) -> str:
    """The file's name, format (PLY encoding, LAS version and point format) and size."""
    fmt = (cloud.format or "?").upper()
    if cloud.format == "ply":
        encoding = _ply_encoding(path)
        fmt += f" ({encoding})" if encoding else ""
    header = cloud.meta.get("las_header")
    if header is not None:
        fmt += f" (version {header.version}, point format {header.point_format.id})"
    return f"{path}  {fmt}, {_human_bytes(path.stat().st_size)}"


def _geometry_lines(cloud) -> list:
    """``(label, text)`` lines: point count, non-finite rows, bounding box, diagonal and spacing."""
    lines = []
    finite = np.isfinite(cloud.points).all(axis=1)
    points = cloud.points[finite]
    distinct = np.unique(np.ascontiguousarray(points).view(np.dtype((np.void, 24)))).shape[0] if points.size else 0
    lines.append(("points", f"{len(cloud)} ({distinct} distinct)"))
    if not finite.all():
        bad = np.flatnonzero(~finite)
        shown = ", ".join(str(r) for r in bad[:5]) + (", ..." if bad.size > 5 else "")
        lines.append(("non-finite", f"{bad.size} row(s) with NaN or infinite coordinates (rows {shown}); "
                                    "compute needs --skip-nonfinite"))
    if points.shape[0]:
        low, high = points.min(axis=0), points.max(axis=0)
        for k, axis in enumerate("xyz"):
            label = "bounding box" if k == 0 else ""
            lines.append((label, f"{axis} {low[k]:14.6g} .. {high[k]:<14.6g} (size {high[k] - low[k]:.6g})"))
        lines.append(("diagonal", f"{float(np.linalg.norm(high - low)):.6g}"))
        unique_points = np.unique(points, axis=0) if distinct < points.shape[0] else points
        spacing = describe_spacing(unique_points)
        sampled = f", over {spacing['queried']} sampled points" if spacing["queried"] < unique_points.shape[0] else ""
        lines.append(("spacing", f"median distance to the nearest neighbour {spacing['nearest']:.6g}, "
                                 f"to the 8th nearest {spacing['eighth']:.6g}{sampled}"))
    return lines


def _property_lines(cloud) -> list:
    """``(label, text)`` lines: normals, colours, and each other field's type and range."""
    lines = []
    if cloud.normals is not None:
        length = np.linalg.norm(cloud.normals, axis=1)
        unit = "unit length" if np.allclose(length[np.isfinite(length)], 1.0, atol=1e-3) else "not unit length"
        lines.append(("normals", f"yes (nx ny nz, {unit})"))
    else:
        lines.append(("normals", "no"))
    lines.append(("colours", "yes (red green blue, 8-bit)" if cloud.colours is not None else "no"))
    if cloud.fields:
        width = max(16, max(len(str(name)) for name in cloud.fields) + 1)
        for k, (name, values) in enumerate(cloud.fields.items()):
            values = np.asarray(values)
            numeric = values.astype(np.float64)
            good = numeric[np.isfinite(numeric)]
            span = f"{good.min():.6g} .. {good.max():.6g}" if good.size else "no finite values"
            nan = f", {numeric.size - good.size} NaN" if good.size < numeric.size else ""
            lines.append(("fields" if k == 0 else "", f"{name:<{width}s} {str(values.dtype):<8s} {span}{nan}"))
    else:
        lines.append(("fields", "none besides the coordinates"))
    return lines


def run(args, log: Log) -> int:
    """Run ``heatcurv info`` on the parsed arguments (prints even with ``--quiet``: it is the output)."""
    cloud = read_cloud(args.input, Log(quiet=True))
    path = Path(args.input)
    lines = [("file", _file_line(cloud, path))] + _geometry_lines(cloud) + _property_lines(cloud)
    for label, text in lines:
        print(f"{label:<13s}{text}")
    return EXIT_OK
