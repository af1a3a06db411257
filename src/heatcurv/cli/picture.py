"""``heatcurv render INPUT -o PICTURE``: a picture of a cloud coloured by a field, read from the file or computed."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..errors import HeatcurvError
from .console import EXIT_OK, Log
from .fields import COMPUTED_FIELDS, DEFAULT_FIELDS, FEATURE_FIELDS, needs_errors
from .options import estimator_kwargs
from .steps import (
    check_output_path,
    computed_values,
    detect_features,
    finite_rows,
    full_rows,
    input_normals,
    orientation_for,
    read_cloud,
    run_estimate,
)

__all__ = ["run"]


def field_from_file(cloud, name: str):
    """Values of field ``name`` held by the file, or None."""
    if name in cloud.fields:
        return np.asarray(cloud.fields[name])
    lowered = {key.lower(): key for key in cloud.fields}
    if name.lower() in lowered:
        return np.asarray(cloud.fields[lowered[name.lower()]])
    axis = {"nx": 0, "ny": 1, "nz": 2}.get(name)
    if axis is not None and cloud.normals is not None:
        return cloud.normals[:, axis]
    axis = {"x": 0, "y": 1, "z": 2}.get(name)
    if axis is not None:
        return cloud.points[:, axis]
    axis = {"red": 0, "green": 1, "blue": 2}.get(name)
    if axis is not None and cloud.colours is not None:
        return cloud.colours[:, axis]
    return None


def file_normals(cloud):
    """The file's normals, as normals or as fields ``nx ny nz``, or None."""
    if cloud.normals is not None:
        return cloud.normals
    if all(name in cloud.fields for name in ("nx", "ny", "nz")):
        return np.column_stack([cloud.fields[name] for name in ("nx", "ny", "nz")])
    return None


def _check_field_options(args) -> None:
    """Fail early on an unknown ``--cmap``, or ``--recompute`` of a field heatcurv does not compute."""
    if args.cmap is not None:
        import matplotlib

        if args.cmap not in matplotlib.colormaps:
            raise HeatcurvError(
                f"unknown colour map {args.cmap!r}; matplotlib has e.g. coolwarm, RdBu_r, viridis, magma"
            )
    if args.recompute and args.field not in COMPUTED_FIELDS:
        raise HeatcurvError(
            f"--recompute: heatcurv does not compute {args.field!r}; it computes {', '.join(COMPUTED_FIELDS)}"
        )


def _field_values(args, cloud, options: dict, log: Log):
    """``(values, camera_normals, reliable)``: the field read from the file, else computed.

    ``camera_normals`` are the file's or the computed normals; ``reliable``
    the file's ``reliable`` field or the computed one, as a bool mask (None
    when there is none).
    """
    field = args.field
    values = None if args.recompute else field_from_file(cloud, field)
    camera_normals = file_normals(cloud)
    reliable = field_from_file(cloud, "reliable")
    reliable = None if reliable is None else np.asarray(reliable) != 0
    if values is not None:
        log.info(f"field {field!r} read from {args.input}")
    elif field in COMPUTED_FIELDS:
        rows = finite_rows(cloud, args.skip_nonfinite)
        points = cloud.points if rows is None else cloud.points[rows]
        normals = input_normals(cloud, args.normals_from_input, rows)
        options = {**options, "orient": orientation_for(cloud, options, normals is not None, log),
                   "se": needs_errors((field,))}
        res = run_estimate(points, normals, options, log, source=args.input)
        feat = detect_features(res, args.feature_threshold, 10.0, log) if field in FEATURE_FIELDS else None
        values = full_rows(computed_values(res, feat, field), rows, len(cloud))
        camera_normals = full_rows(res.normals, rows, len(cloud))
        reliable = full_rows(res.reliable, rows, len(cloud)) == 1
    else:
        present = ["x", "y", "z"] + (["nx", "ny", "nz"] if cloud.normals is not None else []) + (
            ["red", "green", "blue"] if cloud.colours is not None else []) + list(cloud.fields)
        raise HeatcurvError(
            f"{args.input} has no field {field!r} and heatcurv does not compute it; the file holds "
            f"{', '.join(present)}; heatcurv computes {', '.join(COMPUTED_FIELDS)}"
        )
    return values, camera_normals, reliable


def _grey_unreliable(values, reliable, field: str, log: Log):
    """``values`` with the unreliable points' as NaN (drawn grey), for the normals, curvatures and areas."""
    if reliable is None or field not in DEFAULT_FIELDS or field == "reliable":
        return values
    grey = ~reliable & np.isfinite(values)
    if grey.any():
        log.info(f"{int(grey.sum())} unreliable point(s) drawn grey (--unreliable coloured draws them coloured)")
    from ..render import grey_unreliable

    return grey_unreliable(values, ~grey)


def run(args, log: Log) -> int:
    """Run ``heatcurv render`` on the parsed arguments."""
    from ..render import field_style, render_field, supported_picture_formats

    output = check_output_path(args.output, supported_picture_formats(), "picture", args.input)
    _check_field_options(args)
    field = args.field
    options = estimator_kwargs(args)
    cloud = read_cloud(args.input, log)
    values, camera_normals, reliable = _field_values(args, cloud, options, log)
    if args.unreliable == "grey":
        values = _grey_unreliable(np.asarray(values, dtype=np.float64), reliable, field, log)
    vertical = "z" if (cloud.format or "") in ("las", "laz") else "y"
    label = field_style(field).label
    title = args.title if args.title is not None else f"{label} of {Path(args.input).name}"
    tic = time.perf_counter()
    drawn = render_field(
        cloud.points, values, output, field=field, views=args.views, size=args.size, dpi=args.dpi,
        value_range=args.value_range, percentiles=args.percentiles, cmap=args.cmap,
        max_points=args.max_points, point_size=args.point_size, title=title, length_unit=args.unit,
        normals=camera_normals, view=args.view, up=args.up, vertical=vertical, elevation=args.elevation,
        shade=args.shade,
    )
    low, high = drawn.limits
    points = f"a random {drawn.drawn} of {drawn.total}" if drawn.drawn < drawn.total else f"{drawn.drawn}"
    unit = field_style(field).unit_text(args.unit)
    colours = "no / yes" if drawn.kind == "mask" else f"{low:.4g} .. {high:.4g}" + (f" {unit}" if unit else "")
    log.info(f"wrote {output}: {field} of {points} points, {args.views} view(s), "
             f"{drawn.size[0]}x{drawn.size[1]} pixels, colours {colours}")
    shading = {"normals": "shaded by the normals", "estimated normals": "shaded by normals fitted to the points",
               "flat": "flat colours"}[drawn.shading]
    per_view = " per view" if len(drawn.hidden) > 1 else ""
    hidden = (f"; {', '.join(map(str, drawn.hidden))} point(s){per_view} facing away behind the near side hidden"
              if any(drawn.hidden) else "")
    log.detail(f"  {shading}{hidden}; drawing took {time.perf_counter() - tic:.2f} s")
    return EXIT_OK
