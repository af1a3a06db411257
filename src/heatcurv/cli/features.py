"""``heatcurv features INPUT -o OUTPUT``: the sharp-feature mask and score, written next to the file's properties."""

from __future__ import annotations

from .console import EXIT_OK, Log
from .fields import FEATURE_FIELDS
from .steps import check_output_path, detect_features, estimate_input, result_fields, supported_write, write_cloud

__all__ = ["run"]


def run(args, log: Log) -> int:
    """Run ``heatcurv features`` on the parsed arguments."""
    output = check_output_path(args.output, supported_write(), "output", args.input)
    cloud, rows, res = estimate_input(args, log, FEATURE_FIELDS)
    feat = detect_features(res, args.threshold, args.min_angle, log)
    fields, _ = result_fields(res, feat, FEATURE_FIELDS, rows, len(cloud))
    write_cloud(output, cloud, fields, None, log, float64=args.float64)
    return EXIT_OK
