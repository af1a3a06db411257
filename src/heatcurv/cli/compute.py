"""``heatcurv compute INPUT -o OUTPUT``: every curvature field of a point-cloud file, written next to its properties."""

from __future__ import annotations

from ..errors import HeatcurvError
from .console import EXIT_OK, Log
from .fields import DEFAULT_FIELDS, ERROR_FIELDS, FEATURE_FIELDS
from .steps import check_output_path, detect_features, estimate_input, result_fields, supported_write, write_cloud
from .tiled import run_tiled, wants_tiles

__all__ = ["run"]


def run(args, log: Log) -> int:
    """Run ``heatcurv compute`` on the parsed arguments."""
    output = check_output_path(args.output, supported_write(), "output", args.input)
    wanted = args.fields or DEFAULT_FIELDS + (FEATURE_FIELDS if args.features else ())
    want_features = bool(set(wanted) & set(FEATURE_FIELDS))
    _check_error_fields(args, wanted)
    if wants_tiles(args, log):  # the cloud does not fit the memory budget, or a tile flag was given
        run_tiled(args, log, output, wanted)
        return EXIT_OK
    cloud, rows, res = estimate_input(args, log, wanted)  # the standard errors only when written, as in tiles
    feat = detect_features(res, args.feature_threshold, 10.0, log) if want_features else None
    fields, out_normals = result_fields(res, feat, wanted, rows, len(cloud))
    write_cloud(output, cloud, fields, out_normals, log, float64=args.float64)
    return EXIT_OK


def _check_error_fields(args, wanted) -> None:
    """Refuse the standard errors before any work where the run would not compute them."""
    asked = [name for name in wanted if name in ERROR_FIELDS]
    if not asked:
        return
    if args.method == "paper" or getattr(args, "radius", None) is not None:
        given = "--method paper" if args.method == "paper" else "--radius"
        raise HeatcurvError(f"{', '.join(asked)}: standard errors come with the default method's kernel choice, "
                            f"not with {given}")
