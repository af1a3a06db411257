"""``heatcurv geodesic INPUT -o OUTPUT --source I``: the geodesic distance from given points, as a field."""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial import cKDTree

from ..errors import HeatcurvError
from .console import EXIT_OK, Log
from .steps import check_output_path, finite_rows, full_rows, read_cloud, supported_write, write_cloud

__all__ = ["run", "FIELD"]

#: The written field.
FIELD = "geodesic_distance"


def source_rows(cloud, rows, indices, near) -> np.ndarray:
    """The sources as rows of the computed points: ``--source`` file rows, ``--near`` the nearest points.

    Parameters
    ----------
    cloud : PointCloud
    rows : ndarray of int or None
        The file rows computed on (None: all).
    indices : sequence of int
        File rows, counted from 0.
    near : sequence of (3,) tuples
        Coordinates; each picks the nearest computed point.

    Returns
    -------
    ndarray of int, shape (s,)
    """
    n = len(cloud)
    computed = np.arange(n) if rows is None else rows
    position = np.full(n, -1)
    position[computed] = np.arange(computed.size)
    picked = []
    for index in indices:
        if index >= n:
            raise HeatcurvError(f"--source {index}: {cloud.path} has {n} points (rows 0 to {n - 1})")
        if position[index] < 0:
            raise HeatcurvError(f"--source {index}: that row has NaN or infinite coordinates")
        picked.append(position[index])
    if near:
        points = cloud.points[computed]
        picked += list(cKDTree(points).query(np.asarray(near, dtype=float))[1])
    return np.unique(np.asarray(picked, dtype=np.int64))


def run(args, log: Log) -> int:
    """Run ``heatcurv geodesic`` on the parsed arguments."""
    from ..operators.point_laplacian import PointCloudLaplacian

    if not args.source and not args.near:
        raise HeatcurvError("give the sources: --source ROWS (counted from 0) or --near X,Y,Z")
    output = check_output_path(args.output, supported_write(), "output", args.input)
    cloud = read_cloud(args.input, log)
    rows = finite_rows(cloud, args.skip_nonfinite)
    points = cloud.points if rows is None else cloud.points[rows]
    sources = source_rows(cloud, rows, [i for group in args.source for i in group], args.near)
    # the Laplacian wants distinct points: coincident ones get one distance
    distinct, inverse = np.unique(points, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    tic = time.perf_counter()
    log.info(f"geodesic distance from {sources.size} source(s) over {len(distinct)} distinct points")
    lap = PointCloudLaplacian(distinct)
    distance = lap.geodesic_distance(inverse[sources])[inverse]
    log.detail(f"  Laplacian and heat method took {time.perf_counter() - tic:.2f} s")
    unreached = int(np.isinf(distance).sum())
    if unreached:
        log.info(f"{unreached} points lie in parts of the cloud no source reaches (no neighbours join them): "
                 "distance inf")
    finite = distance[np.isfinite(distance)]
    log.info(f"distance from 0 to {finite.max():.6g} (median {np.median(finite):.6g})")
    write_cloud(output, cloud, {FIELD: full_rows(distance, rows, len(cloud))}, None, log, float64=args.float64)
    return EXIT_OK
