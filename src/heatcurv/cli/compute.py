"""``heatcurv compute INPUT -o OUTPUT``: every curvature field of a point-cloud file, written next to its properties."""

from __future__ import annotations

from .console import EXIT_OK, Log
from .fields import DEFAULT_FIELDS, FEATURE_FIELDS
from .steps import check_output_path, detect_features, estimate_input, result_fields, supported_write, write_cloud
from .tiled import run_tiled, wants_tiles

__all__ = ["run"]


def run(args, log: Log) -> int:
    """Run ``heatcurv compute`` on the parsed arguments."""
    output = check_output_path(args.output, supported_write(), "output", args.input)
    wanted = args.fields or DEFAULT_FIELDS + (FEATURE_FIELDS if args.features else ())
    want_features = bool(set(wanted) & set(FEATURE_FIELDS))
    if wants_tiles(args, log):  # the cloud does not fit the memory budget, or a tile flag was given
        run_tiled(args, log, output, wanted)
        return EXIT_OK
    cloud, rows, res = estimate_input(args, log)
    feat = detect_features(res, args.feature_threshold, 10.0, log) if want_features else None
    fields, out_normals = result_fields(res, feat, wanted, rows, len(cloud))
    write_cloud(output, cloud, fields, out_normals, log, float64=args.float64)
    return EXIT_OK
