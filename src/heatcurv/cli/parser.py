"""The argument parser of the ``heatcurv`` command and its subcommands.

Usage errors are one line ``heatcurv: error: ...`` (:class:`UsageError`,
raised instead of argparse's usage dump); each subcommand's parser sets
``run``, the function :func:`heatcurv.cli.main.main` calls with the parsed
arguments.
"""

from __future__ import annotations

import argparse
import os
import sys

from .. import __version__, surfaces
from . import compute, demo, features, geodesic, info, picture, view
from .argtypes import in_range, indices, pair, percentile_pair, picture_size, point3
from .fields import COMPUTED_FIELDS, field_list
from .options import add_estimator_options
from .tiled import add_tile_options

__all__ = ["UsageError", "build_parser", "join_negative_values"]

# options taking one value that may start with '-' (negative coordinates): joined as --opt=value
_VALUE_OPTIONS = ("--viewpoint", "--range", "--view", "--up", "--percentiles", "--near")


class UsageError(Exception):
    """A bad command line: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    """argparse, but usage errors are one line ``heatcurv: error: ...`` (no usage dump)."""

    def error(self, message):
        raise UsageError(f"{message} (see '{self.prog} --help')")


class _Formatter(argparse.HelpFormatter):
    """Wraps one-paragraph descriptions; texts with line breaks (epilogs) stay as written."""

    def __init__(self, prog):
        super().__init__(prog, max_help_position=32, width=min(100, _terminal_width()))

    def _fill_text(self, text, width, indent):
        if "\n" in text:
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


def _terminal_width() -> int:
    try:
        return os.get_terminal_size(sys.stdout.fileno()).columns
    except (OSError, ValueError, AttributeError):
        return 100


def join_negative_values(argv: list) -> list:
    """``['--viewpoint', '-1,2,3']`` -> ``['--viewpoint=-1,2,3']`` so argparse takes the value."""
    joined, k = [], 0
    while k < len(argv):
        token = argv[k]
        if token in _VALUE_OPTIONS and k + 1 < len(argv) and argv[k + 1].startswith("-"):
            joined.append(f"{token}={argv[k + 1]}")
            k += 2
        else:
            joined.append(token)
            k += 1
    return joined


def _add_global_options(parser, *, suppress: bool) -> None:
    """--quiet/--verbose/--debug; on subcommands with SUPPRESS defaults, so either place works."""
    default = argparse.SUPPRESS if suppress else False
    group = parser.add_argument_group("output and diagnostics")
    group.add_argument("-q", "--quiet", action="store_true", default=default,
                       help="no progress bar and no messages, only errors and warnings")
    group.add_argument("-v", "--verbose", action="store_true", default=default,
                       help="also print the time of each stage and the kernel chosen")
    group.add_argument("--debug", action="store_true", default=default,
                       help="show Python tracebacks on errors")


def _add_picture_options(parser) -> None:
    """The options of :func:`heatcurv.render.render_field`."""
    group = parser.add_argument_group("picture")
    group.add_argument("--views", type=in_range("views"), default=1, metavar="N",
                       help="views side by side, 1-36, the camera turned by 360/N degrees about the up "
                       "axis each time (2: front and back) (default: %(default)s)")
    group.add_argument("--size", type=picture_size, default=(1600, 1000), metavar="WxH",
                       help="picture size in pixels (default: 1600x1000)")
    group.add_argument("--dpi", type=in_range("dpi"), default=150,
                       help="dots per inch, 10-2400: the scale of the text (default: %(default)s)")
    group.add_argument("--range", dest="value_range", type=pair, metavar="LOW,HIGH",
                       help="colour limits (default: from the percentiles, symmetric about 0 for a signed "
                       "field whose values change sign)")
    group.add_argument("--percentiles", type=percentile_pair, default=(2.0, 98.0), metavar="LOW,HIGH",
                       help="robust colour range (default: 2,98)")
    group.add_argument("--cmap", metavar="NAME",
                       help="matplotlib colour map (default: coolwarm for signed fields whose values change sign, "
                       "viridis otherwise)")
    group.add_argument("--max-points", type=in_range("max_points"), default=200_000, metavar="N",
                       help="draw a random subset of N points (1-100000000) from larger clouds "
                       "(default: %(default)s)")
    group.add_argument("--point-size", type=in_range("point_size"), metavar="PIXELS",
                       help="disc diameter in pixels, 0.01-1000 (default: from the point spacing, so the "
                       "surface looks closed)")
    group.add_argument("--view", type=point3, metavar="X,Y,Z",
                       help="direction from the cloud towards the camera (default: the cloud's "
                       "thinnest direction, on the side its normals face)")
    group.add_argument("--up", type=point3, metavar="X,Y,Z",
                       help="direction shown up (default: +y, or +z for LAS/LAZ, unless the camera looks along it)")
    group.add_argument("--elevation", type=in_range("elevation"), default=0.0, metavar="DEGREES",
                       help="tilt the camera up by this angle, -90..90 (default: %(default)s)")
    group.add_argument("--no-shade", dest="shade", action="store_false",
                       help="draw the flat colours of the colour bar (default: the points are lit from "
                       "slightly above left of the camera, shaded by their normals, so the shape reads)")
    group.add_argument("--title", help="figure title (default: the field and the file name)")
    group.add_argument("--unit", default="length", metavar="NAME",
                       help="length unit for the colour-bar label, e.g. m gives 1/m (default: %(default)s)")


def _add_cloud_in_and_out(parser, write_exts: str) -> None:
    """The input file and ``-o`` output file of a command that writes a point cloud."""
    parser.add_argument("input", help="point-cloud file")
    parser.add_argument("-o", "--output", required=True, help=f"output file ({write_exts})")


def _add_float64(parser) -> None:
    parser.add_argument("--float64", action="store_true",
                        help="write the computed values in double precision (default: float32 in PLY, "
                        "LAS/LAZ and NPZ, half the size; text files always get 17 digits)")


def _add_compute(add, read_exts: str, write_exts: str) -> None:
    parser = add(
        "compute", "compute curvature fields of a point-cloud file and write them out",
        "Read a point cloud, estimate normals, mean, Gaussian and principal curvatures and "
        "directions and per-point areas, and write them with the input's own properties as "
        "scalar fields named nx ny nz mean gaussian k1 k2 d1x d1y d1z d2x d2y d2z area reliable "
        "(with --features also feature feature_score), which CloudCompare and MeshLab show "
        "as scalar fields. The output format follows the extension; computed values are float32 "
        "in PLY, LAS/LAZ and NPZ (--float64 for double precision), the input's properties and "
        "a PLY mesh's faces are kept. The file is written only once everything is computed, "
        "never over the input; an unwritable output fails before the computation.",
        epilog=f"input formats:  {read_exts}\noutput formats: {write_exts}\n\n"
        "Curvature is in 1/(input length unit), area in (input length unit)^2; a sphere of "
        "radius R\nwith outward normals has mean = k1 = k2 = +1/R. 'reliable' is 0 where a value "
        "is not to be\ntrusted (too few neighbours, border of an open scan, ill-posed fit).\n\n"
        "example:\n  heatcurv compute scan.laz -o scan_curvature.laz --viewpoint 0,0,1.8 -j 4",
    )
    _add_cloud_in_and_out(parser, write_exts)
    parser.add_argument("--fields", type=field_list, metavar="LIST",
                        help="comma-separated fields to write (names above, or normals, d1, d2, "
                        "curvatures, features, border, spacing, neighbours, all) "
                        "(default: all but border, spacing, neighbours)")
    parser.add_argument("--features", action="store_true",
                        help="also detect sharp features: fields feature (0/1) and feature_score (degrees)")
    _add_float64(parser)
    parser.add_argument("--feature-threshold", type=in_range("feature_threshold"), metavar="DEGREES",
                        help="turning angle above which a point is a feature, 0-180 (default: automatic)")
    add_estimator_options(parser)
    add_tile_options(parser)
    _add_global_options(parser, suppress=True)
    parser.set_defaults(run=compute.run)


def _add_render(add) -> None:
    parser = add(
        "render", "draw a picture of a cloud coloured by a field",
        "Draw the point cloud coloured by one field: read from INPUT if it holds the field (a "
        "file written by 'heatcurv compute', or any per-point property of the file), else "
        "computed. Signed fields use a diverging colour map centred at 0, others a sequential "
        "one; the colour range is robust (percentiles); the camera looks along the cloud's "
        "thinnest direction.",
        epilog="fields heatcurv computes: " + " ".join(COMPUTED_FIELDS) + "\n\nexamples:\n"
        "  heatcurv render scan_curvature.ply -o mean.png --field mean --views 2\n"
        "  heatcurv render scan.ply -o features.png --field feature_score --size 1200x900\n"
        "  heatcurv render scan.laz -o k1.pdf --field k1 --range=-0.5,0.5 --unit m",
    )
    parser.add_argument("input", help="point-cloud file")
    parser.add_argument("-o", "--output", required=True, help="picture file (.png, .pdf, .svg, .jpg, ...)")
    parser.add_argument("--field", default="mean",
                        help="field to colour by: mean, gaussian, k1, k2, area, feature, feature_score, "
                        "nx, ..., or any per-point property of the file (default: %(default)s)")
    parser.add_argument("--recompute", action="store_true",
                        help="compute the field even if the file holds one of that name")
    parser.add_argument("--feature-threshold", type=in_range("feature_threshold"), metavar="DEGREES",
                        help="threshold of --field feature, 0-180 (default: automatic)")
    parser.add_argument("--unreliable", choices=("grey", "coloured"), default="grey",
                        help="how to draw the points heatcurv does not trust (its 'reliable' field, read from "
                        "the file or computed) in a picture of a computed field: grey, left out of the colour "
                        "range, or coloured like the others (default: %(default)s)")
    _add_picture_options(parser)
    add_estimator_options(parser)
    _add_global_options(parser, suppress=True)
    parser.set_defaults(run=picture.run)


def _add_features(add, write_exts: str) -> None:
    parser = add(
        "features", "detect sharp features (creases, corners) and write mask and score",
        "Estimate the heat-kernel mean curvature and turn it into a feature score, the turning "
        "angle of the surface around each point in degrees; points above the threshold "
        "(automatic by default: Otsu's split, at least --min-angle) are features. Writes the "
        "fields feature (0/1) and feature_score next to the input's own properties.",
        epilog=f"output formats: {write_exts}\n\nexample:\n  heatcurv features part.ply -o part_features.ply",
    )
    _add_cloud_in_and_out(parser, write_exts)
    parser.add_argument("--threshold", type=in_range("threshold"), metavar="DEGREES",
                        help="turning angle above which a point is a feature, 0-180 (default: automatic)")
    parser.add_argument("--min-angle", type=in_range("min_angle"), default=10.0, metavar="DEGREES",
                        help="floor of the automatic threshold, 0-180 (default: %(default)s)")
    _add_float64(parser)
    add_estimator_options(parser)
    _add_global_options(parser, suppress=True)
    parser.set_defaults(run=features.run)


def _add_geodesic(add, write_exts: str) -> None:
    parser = add(
        "geodesic", "write the geodesic distance from given points, along the surface",
        "Compute the distance along the surface from the nearest of the given points to every point, by "
        "the heat method on heatcurv's Laplacian (no mesh), and write it as the field geodesic_distance "
        "next to the input's own properties. Points in parts of the cloud that no neighbour joins to a "
        "source get inf.",
        epilog=f"output formats: {write_exts}\n\nexamples:\n"
        "  heatcurv geodesic bunny.ply -o bunny_distance.ply --source 0\n"
        "  heatcurv geodesic part.las -o part_distance.laz --near 12.5,3.0,41.2 --near 15,3,40",
    )
    _add_cloud_in_and_out(parser, write_exts)
    parser.add_argument("--source", type=indices, action="append", default=[], metavar="ROWS",
                        help="source points by their rows in the file, counted from 0, e.g. 0 or 12,40 (repeatable)")
    parser.add_argument("--near", type=point3, action="append", default=[], metavar="X,Y,Z",
                        help="the point nearest to X,Y,Z is a source (repeatable)")
    parser.add_argument("--skip-nonfinite", action="store_true",
                        help="leave out points with NaN or infinite coordinates (their distance is NaN) "
                        "instead of stopping")
    _add_float64(parser)
    _add_global_options(parser, suppress=True)
    parser.set_defaults(run=geodesic.run)


def _add_info(add, read_exts: str) -> None:
    parser = add(
        "info", "describe a point-cloud file: points, bounding box, spacing, fields",
        "Print the number of points (and of distinct points), the bounding box, the median "
        "spacing (nearest-neighbour and 8th-neighbour distances) and the fields the file holds.",
        epilog=f"formats: {read_exts}",
    )
    parser.add_argument("input", help="point-cloud file")
    _add_global_options(parser, suppress=True)
    parser.set_defaults(run=info.run)


def _add_view(add, read_exts: str) -> None:
    from ..view import DEFAULT_MAX_POINTS

    parser = add(
        "view", "write an interactive 3-D view of a cloud and its fields: one HTML page",
        "Write one self-contained HTML page (WebGL, nothing fetched from the network) showing the "
        "cloud coloured by any of its scalar fields: turn it with the mouse, zoom with the wheel, "
        "choose the field from a menu. Colours and their robust limits are those of 'heatcurv "
        "render'; points without a value, and points heatcurv marks unreliable in the fields it "
        "computed, are grey; a file's normals shade the points. Opens the page in the web browser "
        "when there is one, else says where it is.",
        epilog=f"input formats: {read_exts}\n\n"
        "examples:\n"
        "  heatcurv compute scan.ply -o scan_curvature.ply && heatcurv view scan_curvature.ply\n"
        "  heatcurv view scan_curvature.laz -o scan.html --field k1 --fields k1,k2,mean,reliable",
    )
    parser.add_argument("input", help="point-cloud file")
    parser.add_argument("-o", "--output", metavar="PAGE",
                        help="the page, .html (default: INPUT with the extension .html)")
    parser.add_argument("--field", help="field shown first (default: mean if the file has it, else its first field)")
    parser.add_argument("--fields", type=view.field_names, metavar="LIST",
                        help="comma-separated fields to put in the page (fewer fields: a smaller page; x, y, z "
                        "are always there, at no cost) (default: every scalar field of the file)")
    parser.add_argument("--max-points", type=in_range("max_points"), default=DEFAULT_MAX_POINTS, metavar="N",
                        help="show a random subset of N points (1-100000000) of larger clouds: each point "
                        "costs about 5.3 bytes per field in the page (default: %(default)s)")
    parser.add_argument("--percentiles", type=percentile_pair, default=(2.0, 98.0), metavar="LOW,HIGH",
                        help="robust colour range (default: 2,98)")
    parser.add_argument("--title", help="page title (default: the file name)")
    parser.add_argument("--unit", default="length", metavar="NAME",
                        help="length unit for the labels, e.g. m gives 1/m (default: %(default)s)")
    parser.add_argument("--no-browser", action="store_true",
                        help="do not open the page in the web browser, only say where it is")
    _add_global_options(parser, suppress=True)
    parser.set_defaults(run=view.run)


def _add_demo(add) -> None:
    parser = add(
        "demo", "run on a built-in example: errors against exact values and a picture",
        "Sample an analytic surface, estimate its curvature with the default and the paper's "
        "method, print the errors against the exact values and draw the mean curvature. With "
        "--bunny: compute and draw the curvature of the Stanford bunny scan shipped with heatcurv.",
    )
    parser.add_argument("--surface", default="torus", choices=sorted(surfaces.SURFACES),
                        help="surface (default: the paper's torus)")
    parser.add_argument("-n", type=in_range("n"), default=20000,
                        help="number of points, 4-10000000 (default: %(default)s)")
    parser.add_argument("--sampler", default="random", choices=surfaces.SAMPLERS,
                        help="sampler (default random: area-uniform, irregular like a scan)")
    parser.add_argument("--noise", type=in_range("noise"), default=0.0,
                        help="Gaussian noise, fraction of the bounding-box diagonal, 0-1")
    parser.add_argument("--seed", type=in_range("seed"), default=0, help="random seed (>= 0)")
    parser.add_argument("--bunny", action="store_true",
                        help="the real Stanford bunny scan instead of an analytic surface")
    parser.add_argument("-o", "--output", metavar="PICTURE",
                        help="picture of the mean curvature (default: heatcurv_demo.png, with --bunny "
                        "heatcurv_bunny.png, in the current directory)")
    parser.add_argument("--no-picture", action="store_true", help="do not draw the picture")
    _add_global_options(parser, suppress=True)
    parser.set_defaults(run=demo.run)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``heatcurv`` command."""
    from ..io import SUPPORTED_READ, SUPPORTED_WRITE

    read_exts, write_exts = " ".join(SUPPORTED_READ), " ".join(SUPPORTED_WRITE)
    parser = _Parser(
        prog="heatcurv",
        description="Mesh-free curvature of point clouds with the heat kernel: normals, mean, "
        "Gaussian and principal curvatures and directions, areas and sharp features, "
        "from a scanner's or a photogrammetry tool's file.",
        epilog="examples:\n"
        "  heatcurv info scan.ply\n"
        "  heatcurv compute scan.ply -o scan_curvature.ply\n"
        "  heatcurv render scan_curvature.ply -o mean.png --field mean --views 2\n"
        "  heatcurv view scan_curvature.ply\n"
        "  heatcurv geodesic scan.ply -o scan_distance.ply --source 0\n"
        "  heatcurv demo\n\n"
        "Run 'heatcurv COMMAND --help' for a command's options.",
        formatter_class=_Formatter,
    )
    parser.add_argument("--version", action="version", version=f"heatcurv {__version__}")
    _add_global_options(parser, suppress=False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    def add(name, help_text, description, epilog=None):
        return sub.add_parser(name, help=help_text, description=description, epilog=epilog,
                              formatter_class=_Formatter)

    _add_compute(add, read_exts, write_exts)
    _add_render(add)
    _add_features(add, write_exts)
    _add_geodesic(add, write_exts)
    _add_info(add, read_exts)
    _add_view(add, read_exts)
    _add_demo(add)
    return parser
