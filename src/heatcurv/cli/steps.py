"""The steps the commands share: check the output, read, estimate (with the progress bar), detect features, write.

Each step prints what it did through the command's :class:`~.console.Log`
and raises :class:`~heatcurv.errors.HeatcurvError` with a one-line message.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import HeatcurvError
from .console import Log
from .fields import COMPUTED_FIELDS, FEATURE_FIELDS, needs_errors
from .options import estimator_kwargs
from .progressbar import StageProgress

__all__ = [
    "check_output_path", "same_file", "supported_write", "read_cloud", "finite_rows", "input_normals",
    "orientation_for", "run_estimate",
    "detect_features", "full_rows", "computed_values", "result_fields", "write_cloud",
]


def check_output_path(path, extensions, what: str, input_path=None) -> Path:
    """Fail early (before reading or computing anything) on an output that cannot or must not be written.

    Refused: an extension the writer does not know, the input file itself
    (also through another spelling of its path, a symbolic or a hard link),
    a missing or unwritable directory, an existing read-only file
    (:func:`heatcurv.io.check_writable`).
    """
    from ..io import check_writable

    path = Path(path)
    ext = path.suffix.lower()
    if ext not in extensions:
        raise HeatcurvError(
            f"cannot write {path}: unknown {what} extension {ext or '(none)'!r}; supported: {' '.join(extensions)}"
        )
    if input_path is not None and same_file(path, input_path):
        raise HeatcurvError(
            f"cannot write {path}: it is the input file {input_path}; heatcurv never overwrites its input, "
            "choose another output name"
        )
    return check_writable(path)


def same_file(path, other) -> bool:
    """Whether ``path`` and ``other`` name the same file (:func:`os.path.samefile` where both exist)."""
    try:
        return os.path.samefile(path, other)
    except OSError:  # one of them does not exist (yet)
        return os.path.normcase(os.path.abspath(path)) == os.path.normcase(os.path.abspath(other))


def supported_write():
    """The extensions :func:`heatcurv.io.write_points` writes."""
    from ..io import SUPPORTED_WRITE

    return SUPPORTED_WRITE


def read_cloud(path, log: Log):
    """:func:`heatcurv.io.read_points`, saying what was read."""
    from ..io import read_points

    tic = time.perf_counter()
    cloud = read_points(path)
    extras = []
    if cloud.normals is not None:
        extras.append("normals")
    if cloud.colours is not None:
        extras.append("colours")
    if cloud.fields:
        extras.append(f"{len(cloud.fields)} other field(s)")
    log.info(f"read {path}: {len(cloud)} points ({(cloud.format or '?').upper()}"
             f"{', ' + ', '.join(extras) if extras else ''})")
    log.detail(f"  reading took {time.perf_counter() - tic:.2f} s")
    return cloud


def finite_rows(cloud, skip_nonfinite: bool) -> np.ndarray | None:
    """Row numbers with finite coordinates, or None if all are; an error unless skipping."""
    finite = np.isfinite(cloud.points).all(axis=1)
    if finite.all():
        return None
    bad = np.flatnonzero(~finite)
    if not skip_nonfinite:
        shown = ", ".join(str(r) for r in bad[:5]) + (", ..." if bad.size > 5 else "")
        raise HeatcurvError(
            f"{cloud.path}: {bad.size} of {len(cloud)} points have NaN or infinite coordinates "
            f"(rows {shown}, counted from 0); remove them or pass --skip-nonfinite"
        )
    return np.flatnonzero(finite)


def input_normals(cloud, use: bool, rows):
    """The file's normals of ``rows`` (``--normals-from-input``), or None if not ``use``."""
    if not use:
        return None
    if cloud.normals is None:
        raise HeatcurvError(
            f"{cloud.path} has no normals (nx ny nz); drop --normals-from-input to estimate them"
        )
    return cloud.normals if rows is None else cloud.normals[rows]


def estimate_input(args, log: Log, fields):
    """Read ``args.input`` and estimate on it with the command line's options (validated first).

    ``fields``: the fields the command writes; the standard errors are
    computed only when one of them is (:func:`.fields.needs_errors`).

    Returns
    -------
    cloud : PointCloud
        The file as read.
    rows : ndarray of int or None
        The rows computed on (``--skip-nonfinite``), None for all.
    res : CurvatureResult
        The estimate on those rows.
    """
    options = estimator_kwargs(args)  # bad option values fail before a big file is read
    cloud = read_cloud(args.input, log)
    rows = finite_rows(cloud, args.skip_nonfinite)
    points = cloud.points if rows is None else cloud.points[rows]
    normals = input_normals(cloud, args.normals_from_input, rows)
    options["orient"] = orientation_for(cloud, options, normals is not None, log)
    options["coordinate_precision"] = coordinate_precision(cloud)
    options["se"] = needs_errors(fields)
    return cloud, rows, run_estimate(points, normals, options, log, source=args.input)


def coordinate_precision(cloud):
    """The step of the grid a file's coordinates are stored on: a LAS/LAZ file's scales, else None.

    None leaves it to :func:`heatcurv.estimate`, which finds float32 coordinates by
    their values (the readers return float64 arrays of them).
    """
    header = cloud.meta.get("las_header")
    return None if header is None else np.asarray(header.scales, dtype=np.float64)


#: Formats whose clouds have a vertical axis: their normals are oriented up (+z) by default.
UP_FORMATS = ("las", "laz")


def orientation_for(cloud, options: dict, given_normals: bool, log: Log) -> str | None:
    """``--orient`` as given, or the command line's choice for ``auto``: up (+z) for LAS/LAZ.

    Aerial and terrestrial LiDAR users expect normals towards the sky (or the
    scanner, with ``--viewpoint``), which "outward" does not give on an open
    tile of terrain, roofs and trees.
    """
    orient = options.get("orient")
    if orient not in (None, "auto") or given_normals or options.get("viewpoint") is not None:
        return orient
    if cloud.format in UP_FORMATS:
        log.info(f"orienting normals up (+z), as for terrain and aerial LiDAR ({cloud.format.upper()} input); "
                 "--orient outward for a closed object, --viewpoint X,Y,Z for a scanner position")
        return "up"
    return orient


def run_estimate(points, normals, options: dict, log: Log, source=None):
    """:func:`heatcurv.estimate` with a progress bar on a terminal, and the messages around it.

    A :class:`HeatcurvError` (too few points, collinear points, ...) is
    re-raised with the name of the ``source`` file in front.
    """
    from ..estimator import estimate

    progress = StageProgress(enabled=not log.quiet and sys.stderr.isatty(), method=options.get("method", "default"))
    tic = time.perf_counter()
    try:
        res = estimate(points, normals, progress=progress, **options)
    except HeatcurvError as exc:
        if source is None:
            raise
        raise HeatcurvError(f"{source}: {exc}") from exc
    finally:
        progress.close()
    seconds = time.perf_counter() - tic
    scale = res.info.get("scale")
    kernel = f", kernel {scale.fit}" if scale else ""
    outliers = int(res.outlier.sum())
    log.info(
        f"estimated curvature in {seconds:.2f} s (method {res.options.method}{kernel}): "
        f"{int(res.reliable.sum())} of {len(res)} points reliable"
        + (f", {outliers} outlier(s) (stray points, no area)" if outliers else "")
    )
    log.info(f"surface area {res.area.sum():.6g} (reliable points: {res.area[res.reliable].sum():.6g}), "
             "in the cloud's unit squared")
    precision = res.info.get("precision")
    if precision is not None and precision.flagged:
        log.info(f"coordinates too coarse for the curvature: {precision.reason}")
    orientation = res.info.get("orientation")
    policy = getattr(orientation, "policy", None)
    if policy is not None and policy.mode == "up" and policy.towards is None:
        log.info("normals oriented up (+z): the cloud is an open surface over the horizontal plane "
                 "(--orient outward for a closed object, --viewpoint X,Y,Z for a scanner position)")
    elif policy is not None and policy.mode == "up":
        log.info(f"normals oriented {policy.along}: the cloud is an open surface over the plane across that "
                 "axis (--orient outward for a closed object, --viewpoint X,Y,Z for a scanner position)")
    elif policy is not None and orientation.closed is False:
        log.info("normals oriented outward of each piece (its convex side): the cloud is open and not a surface over "
                 "the horizontal plane (--orient up for terrain, --viewpoint X,Y,Z for a scanner position)")
    if orientation is not None and orientation.turned:
        log.info(f"{orientation.turned} point(s) of parts the spanning tree had turned inside out were turned "
                 "outward by the winding number")
    if orientation is not None and orientation.escaped:
        log.info(f"{orientation.escaped} point(s) not reliable were turned to the side their rays escape from "
                 "(outward of the closed object; still flagged unreliable)")
    if orientation is not None and orientation.ambiguous:
        why = ", or a side the winding number contradicts" if orientation.unsupported else ""
        log.info(f"{orientation.ambiguous} point(s) have no consistent side for their normal (two sheets closer "
                 f"than the kernel, or no way to tell up from down{why}): flagged unreliable")
    sheets = res.info.get("second_sheet", 0)
    if sheets:
        log.info(f"{sheets} point(s) have both sides of a thin part in their neighbourhood (a part a few spacings "
                 "thick): no area, flagged unreliable")
    if log.verbose:
        _report_details(res, log)
    return res


def _report_details(res, log: Log) -> None:
    """``--verbose``: stage timings, the fit plan and its kernel, the area solve and duplicates."""
    scale = res.info.get("scale")
    timings = res.info.get("timings", {})
    width = max([len(stage) for stage in timings] + [len("total")])
    log.detail("  stage timings:")
    for stage, value in timings.items():
        log.detail(f"    {stage:<{width}s} {value:8.3f} s")
    log.detail(f"    {'total':<{width}s} {sum(timings.values()):8.3f} s")
    plan = res.info.get("plan")
    if plan is not None:
        log.detail(f"  fit plan: {plan.describe()}")
    if scale:
        log.detail(
            f"  kernel: {scale.fit} ({'median ' if res.options.radius is not None else ''}{scale.k} "
            f"neighbours; ball radius {scale.median_radius:.4g} median, {scale.radius:.4g} 99th percentile, in the "
            f"cloud's unit; spacing h {scale.median_h:.4g}); "
            f"noise sigma {scale.sigma:.3g} ({scale.relative_noise:.3g} h)"
        )
        if scale.anchors:
            log.detail(f"  fitted at {scale.anchors} anchors; support radius {scale.support_radius:.4g} (with the "
                       "cloud-wide choices fixed, no point farther changes a point's values)")
    if plan is not None and plan.refit:
        log.detail("  very low noise (such as millimetre rounding): the kernel one doubling wider than chosen, "
                   "the anchors' quartic refit and the regression of their tensors")
    orientation = res.info.get("orientation")
    if orientation is not None and orientation.mode != "given":
        log.detail(f"  orientation: {orientation.mode}; {orientation.components} component(s); "
                   f"{orientation.anchored} point(s) read off the reference direction, "
                   f"{orientation.by_convention} by a convention on the coordinates, {orientation.ambiguous} ambiguous")
        if orientation.reason:
            log.detail(f"  orientation chosen: {orientation.reason}")
    solve = res.info.get("area_solve")
    if res.options.area_method == "system" and solve is not None:
        log.detail(f"  area system H A = 1: {solve.solver}, {solve.iterations} iterations, "
                   f"residual {solve.residual:.2e}")
    n_distinct = res.info.get("n_distinct")
    if n_distinct is not None and n_distinct != len(res):
        log.detail(f"  {len(res) - n_distinct} duplicate point(s) share their twin's values")


def detect_features(res, threshold, min_angle, log: Log):
    """:func:`heatcurv.sharp_features` of a result, saying how many points are features."""
    from ..features import sharp_features

    feat = sharp_features(res, threshold=threshold, min_angle=min_angle)
    count = int(feat.mask.sum())
    log.info(f"sharp features: {count} of {len(res)} points ({100.0 * count / max(len(res), 1):.1f} %) "
             f"turn by more than {feat.threshold:.1f} degrees")
    return feat


def full_rows(values: np.ndarray, rows, n: int) -> np.ndarray:
    """``values`` of the computed rows spread to all ``n`` rows (NaN, False or 0 elsewhere).

    Masks stay boolean and counts (``neighbours``) integer, with 0 on the
    rows not computed, so that they are written as integers.
    """
    values = np.asarray(values)
    if rows is None:
        return values
    fill = np.nan if values.dtype.kind == "f" else 0
    full = np.full((n,) + values.shape[1:], fill, dtype=values.dtype)
    full[rows] = values
    return full


def computed_values(res, feat, name: str) -> np.ndarray:
    """Field ``name`` (one of :data:`~.fields.COMPUTED_FIELDS`) of a result, on the computed rows."""
    if name in FEATURE_FIELDS:
        return feat.mask if name == "feature" else feat.score
    if name in ("nx", "ny", "nz"):
        return res.normals[:, "xyz".index(name[1])]
    if name[:2] in ("d1", "d2"):
        return getattr(res, name[:2])[:, "xyz".index(name[2])]
    values = getattr(res, name)
    if values is None:  # the standard errors: the chord fit's, on a whole cloud
        raise HeatcurvError(f"{name} is not computed with method={res.options.method!r}"
                            + (" and --radius" if res.options.radius is not None else "")
                            + "; standard errors come with the default method's kernel choice")
    return values


def result_fields(res, feat, wanted, rows, n: int) -> tuple[dict, np.ndarray | None]:
    """The arrays to write, ``(fields, normals)``, for :func:`heatcurv.io.write_points`.

    Fields come in the order of :data:`~.fields.COMPUTED_FIELDS`; a complete triple
    ``d1x d1y d1z`` is passed as one (n, 3) field ``d1``, which every format
    writes as the same three names. Rows not
    computed (``rows``) get NaN, or 0 in masks and counts.
    """
    wanted = set(wanted)
    normals = full_rows(res.normals, rows, n) if "nx" in wanted else None
    fields = {}
    for name in COMPUTED_FIELDS:
        if name not in wanted or name in ("nx", "ny", "nz"):
            continue
        vector = name[:2] if name[:2] in ("d1", "d2") else None
        if vector is not None and {vector + a for a in "xyz"} <= wanted:
            if vector not in fields:
                fields[vector] = full_rows(getattr(res, vector), rows, n)
            continue
        fields[name] = full_rows(computed_values(res, feat, name), rows, n)
    return fields, normals


def write_cloud(path, cloud, fields: dict, normals, log: Log, *, float64: bool = False) -> None:
    """:func:`heatcurv.io.write_points` of the input's points and properties plus ``fields``, saying what.

    The computed values are float32 in PLY, LAS/LAZ and NPZ unless ``float64``
    (``--float64``); a warning says so if the input's faces cannot be written.
    """
    from ..io import write_points

    tic = time.perf_counter()
    write_points(path, cloud.points, fields, normals=normals, source=cloud, dtype="float64" if float64 else None)
    names = []
    for name, values in fields.items():
        names += [name + a for a in "xyz"] if np.ndim(values) == 2 else [name]
    if normals is not None:
        names = ["nx", "ny", "nz"] + names
    log.info(f"wrote {path}: {len(cloud)} points, fields {' '.join(names)}")
    log.detail(f"  writing took {time.perf_counter() - tic:.2f} s")
