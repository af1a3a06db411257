"""``heatcurv features INPUT -o OUTPUT``: the sharp-feature mask and score, written next to the file's properties."""

from __future__ import annotations

from .console import EXIT_OK, Log
from .fields import FEATURE_FIELDS
from .options import estimator_kwargs
from .steps import (
    check_output_path,
    detect_features,
    finite_rows,
    input_normals,
    read_cloud,
    result_fields,
    run_estimate,
    supported_write,
    write_cloud,
)

__all__ = ["run"]


def run(args, log: Log) -> int:
    """Run ``heatcurv features`` on the parsed arguments."""
    output = check_output_path(args.output, supported_write(), "output")
    options = estimator_kwargs(args)
    cloud = read_cloud(args.input, log)
    rows = finite_rows(cloud, args.skip_nonfinite)
    points = cloud.points if rows is None else cloud.points[rows]
    normals = input_normals(cloud, args.normals_from_input, rows)
    res = run_estimate(points, normals, options, log, source=args.input)
    feat = detect_features(res, args.threshold, args.min_angle, log)
    fields, _ = result_fields(res, feat, FEATURE_FIELDS, rows, len(cloud))
    write_cloud(output, cloud, fields, None, log)
    return EXIT_OK
