"""The ``heatcurv`` command line (``heatcurv ...`` or ``python -m heatcurv ...``).

Subcommands
-----------
``compute INPUT -o OUTPUT``
    Read a point cloud (PLY, LAS/LAZ, XYZ/TXT/CSV/PTS, OBJ, OFF, NPY/NPZ),
    run :func:`heatcurv.estimate` and write every field (``nx ny nz mean
    gaussian k1 k2 d1x d1y d1z d2x d2y d2z area reliable``, with
    ``--features`` also ``feature feature_score``) next to the input's own
    properties, in the format of OUTPUT's extension.
``render INPUT -o PICTURE``
    A picture of the cloud coloured by one field, read from INPUT if it holds
    it (a file written by ``compute``) or computed (:mod:`heatcurv.render`).
``features INPUT -o OUTPUT``
    Sharp-feature mask and score (:func:`heatcurv.sharp_features`).
``info INPUT``
    Point count, bounding box, spacing and the fields a file holds.
``demo``
    The main job on a built-in example: an analytic surface (errors against
    the exact values and a picture), or with ``--bunny`` the Stanford bunny
    scan shipped with heatcurv.

Global options ``--quiet``, ``--verbose`` and ``--debug`` go before or after
the subcommand. Reports (what was read, computed and written; ``--verbose``:
stage timings and the kernel chosen) go to stdout; stderr holds only errors,
warnings and, when it is a terminal, a progress bar.

Exit status: 0 on success; 2 on bad input or options, with one line
``heatcurv: error: ...`` on stderr and no output file; 1 on an unexpected
error (a bug: one line, ``--debug`` shows the traceback); 130 when
interrupted.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from . import __version__, surfaces
from .errors import HeatcurvError, HeatcurvWarning

__all__ = ["main", "build_parser"]

EXIT_OK = 0
EXIT_BUG = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130

#: Scalar fields ``compute`` writes by default, in this order (normals as ``nx ny nz``).
DEFAULT_FIELDS = (
    "nx", "ny", "nz", "mean", "gaussian", "k1", "k2",
    "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area", "reliable",
)
#: Fields of the sharp-feature detector.
FEATURE_FIELDS = ("feature", "feature_score")
#: Further fields ``--fields`` can ask for.
EXTRA_FIELDS = ("border", "spacing", "neighbours")
#: Every field heatcurv computes, in the written order.
COMPUTED_FIELDS = DEFAULT_FIELDS + FEATURE_FIELDS + EXTRA_FIELDS
#: Shorthands of ``--fields``.
FIELD_GROUPS = {
    "normals": ("nx", "ny", "nz"),
    "d1": ("d1x", "d1y", "d1z"),
    "d2": ("d2x", "d2y", "d2z"),
    "curvatures": ("mean", "gaussian", "k1", "k2"),
    "default": DEFAULT_FIELDS,
    "features": FEATURE_FIELDS,
    "all": COMPUTED_FIELDS,
}

# options taking one value that may start with '-' (negative coordinates): joined as --opt=value
_VALUE_OPTIONS = ("--viewpoint", "--range", "--view", "--up", "--percentiles")

# share of the run time of each stage of estimate(), for the progress bar
_STAGE_WEIGHTS = {
    "validate": 1, "neighbours": 6, "spacing": 1, "areas": 10,
    "normals": 4, "orientation": 4, "mean": 6, "principal": 68,
}


# ----------------------------------------------------------------------------- plumbing


class _UsageError(Exception):
    """A bad command line: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    """argparse, but usage errors are one line ``heatcurv: error: ...`` (no usage dump)."""

    def error(self, message):
        raise _UsageError(f"{message} (see '{self.prog} --help')")


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


class _Log:
    """Messages on stdout: ``info`` unless ``--quiet``, ``detail`` only with ``--verbose``.

    stderr holds only errors, warnings and the progress bar, so a failed run
    leaves exactly one line there.
    """

    def __init__(self, quiet: bool = False, verbose: bool = False, stream=None):
        self.quiet, self.verbose = quiet, verbose and not quiet
        self.stream = stream if stream is not None else sys.stdout

    def info(self, message: str) -> None:
        if not self.quiet:
            print(message, file=self.stream, flush=True)

    def detail(self, message: str) -> None:
        if self.verbose:
            print(message, file=self.stream, flush=True)


class StageProgress:
    """One tqdm bar over the stages of :func:`heatcurv.estimate`, fed by its ``progress`` callback.

    Parameters
    ----------
    enabled : bool
        Draw the bar; otherwise calls do nothing.
    stream : file, optional
        Where the bar goes (stderr).

    Notes
    -----
    The bar runs 0-100 %, each stage weighted by its usual share of the run
    time (the curvature fit, which reports its blocks, about two thirds); the
    description names the running stage.
    """

    def __init__(self, enabled: bool, stream=None):
        self.bar = None
        self.done = 0.0
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(
                total=100, file=stream if stream is not None else sys.stderr, leave=False,
                bar_format="{desc:<12}{percentage:3.0f}%|{bar}| {elapsed}", mininterval=0.1,
                dynamic_ncols=True,
            )

    def __call__(self, stage: str, fraction: float) -> None:
        if self.bar is None:
            return
        from .progress import STAGES

        before = sum(_STAGE_WEIGHTS.get(s, 0) for s in STAGES[: STAGES.index(stage)]) if stage in STAGES else self.done
        position = min(100.0, before + _STAGE_WEIGHTS.get(stage, 0) * float(fraction))
        self.done = max(self.done, position)
        self.bar.set_description_str(stage, refresh=False)
        self.bar.n = self.done
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _join_negative_values(argv: list) -> list:
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


# ----------------------------------------------------------------------------- argument types


def _numbers(text: str, count: int, what: str) -> tuple:
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return values


def _point3(text: str) -> tuple:
    return _numbers(text, 3, "three numbers X,Y,Z")


def _pair(text: str) -> tuple:
    low, high = _numbers(text, 2, "two numbers LOW,HIGH")
    if not low < high:
        raise argparse.ArgumentTypeError(f"expected LOW < HIGH, got {text!r}")
    return low, high


def _percentile_pair(text: str) -> tuple:
    low, high = _pair(text)
    if not (0 <= low and high <= 100):
        raise argparse.ArgumentTypeError(f"percentiles must lie in 0..100, got {text!r}")
    return low, high


def _picture_size(text: str) -> tuple:
    match = re.fullmatch(r"\s*(\d+)\s*[xX*,]\s*(\d+)\s*", text)
    if not match:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels (e.g. 1600x900), got {text!r}")
    width, height = int(match[1]), int(match[2])
    if not (100 <= width <= 10000 and 100 <= height <= 10000):
        raise argparse.ArgumentTypeError(f"width and height must be 100-10000 pixels, got {text!r}")
    return width, height


def _int_at_least(minimum: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value == 0 or value < -1:
        raise argparse.ArgumentTypeError(f"expected -1 (all cores) or a thread count >= 1, got {value}")
    return value


def _kernel_scale(text: str):
    if text == "auto":
        return "auto"
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'auto' or a neighbour count, got {text!r}") from None
    if value < 20:
        raise argparse.ArgumentTypeError(f"a neighbour count must be at least 20, got {value}")
    return value


def _field_list(text: str) -> tuple:
    names = [n for n in re.split(r"[,\s]+", text.strip()) if n]
    if not names:
        raise argparse.ArgumentTypeError("expected a comma-separated list of field names")
    chosen = set()
    for name in names:
        if name in FIELD_GROUPS:
            chosen.update(FIELD_GROUPS[name])
        elif name in COMPUTED_FIELDS:
            chosen.add(name)
        else:
            known = ", ".join(list(COMPUTED_FIELDS) + list(FIELD_GROUPS))
            raise argparse.ArgumentTypeError(f"unknown field {name!r}; choose from {known}")
    if chosen & set(FIELD_GROUPS["normals"]):  # normals are written as a triple
        chosen.update(FIELD_GROUPS["normals"])
    return tuple(name for name in COMPUTED_FIELDS if name in chosen)


# ----------------------------------------------------------------------------- parser


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


def _add_estimate_options(parser, *, viewpoint: bool = True) -> None:
    """The options of :func:`heatcurv.estimate`; None means the method's value."""
    from .pipeline import METHODS

    default, paper = METHODS["default"], METHODS["paper"]

    def show(value):
        return "not used" if value is None else f"{value:g}" if isinstance(value, float) else str(value)

    def presets(name):
        ours, theirs = getattr(default, name), getattr(paper, name)
        if ours == theirs:
            return f"(default: {show(ours)})"
        return f"(default method: {show(ours)}; paper: {show(theirs)})"

    group = parser.add_argument_group(
        "curvature estimation", "Options of heatcurv.estimate; each overrides the --method preset."
    )
    group.add_argument("--method", choices=("default", "paper"), default="default",
                       help="preset: 'default' is built for irregular, scanned and noisy clouds; "
                       "'paper' follows the paper literally (accurate on regular samples only) "
                       "(default: %(default)s)")
    group.add_argument("--alpha", type=_positive_float, metavar="A",
                       help=f"ball radius in units of the spacing, r = alpha h {presets('alpha')}")
    group.add_argument("--m", type=_positive_float, metavar="M",
                       help=f"diffusion time t = m h^2 {presets('m')}")
    group.add_argument("--spacing", choices=("global", "local", "density"),
                       help=f"spacing h: eq 2.6, eq 2.7 or from the density {presets('spacing')}")
    group.add_argument("--gamma", type=_float, metavar="G",
                       help=f"blend of eq 2.7, in [0, 1] {presets('gamma')}")
    group.add_argument("--k-local", type=_int_at_least(2), metavar="K",
                       help=f"neighbours of eq 2.7's min/max {presets('k_local')}")
    group.add_argument("--neighbors", type=_int_at_least(20), metavar="K",
                       help=f"neighbours in the density ball, and the narrowest chord-fit kernel {presets('neighbors')}")
    group.add_argument("--scale", type=_kernel_scale, metavar="auto|K",
                       help="chord-fit kernel: 'auto' (chosen from the measured noise) or a fixed "
                       f"neighbour count >= 20 {presets('scale')}")
    group.add_argument("--area-method", choices=("system", "density"),
                       help=f"per-point areas from H A = 1 or a density estimate {presets('area_method')}")
    group.add_argument("--area-solver", choices=("auto", "cg", "bicgstab", "direct"),
                       help=f"solver of H A = 1 {presets('area_solver')}")
    group.add_argument("--mean-formula", choices=("projection", "norm"),
                       help=f"mean curvature 1/2 K.n (eq 2.12) or 1/2 |K| (eq 2.11) {presets('mean_formula')}")
    group.add_argument("--fit", choices=("chord", "constrained", "unconstrained"),
                       help=f"principal-curvature fit {presets('fit')}")
    group.add_argument("--min-neighbors", type=_int_at_least(3), metavar="K",
                       help=f"fewest neighbours per point {presets('min_neighbors')}")
    if viewpoint:
        normals = group.add_mutually_exclusive_group()
        normals.add_argument("--viewpoint", type=_point3, metavar="X,Y,Z",
                             help="orient the estimated normals towards this sensor position "
                             "(input coordinates; negative values are fine: --viewpoint -10,0,2)")
        normals.add_argument("--normals-from-input", action="store_true",
                             help="use the input file's normals (nx ny nz) instead of estimating them; "
                             "curvature signs follow them")
    group.add_argument("-j", "--workers", type=_workers, default=-1, metavar="N",
                       help="threads (-1: all cores) (default: %(default)s)")
    group.add_argument("--skip-nonfinite", action="store_true",
                       help="compute on the rows with finite coordinates and give the others NaN "
                       "(default: such rows are an error)")


def _add_picture_options(parser) -> None:
    group = parser.add_argument_group("picture")
    group.add_argument("--views", type=_int_at_least(1), default=1, metavar="N",
                       help="views side by side, the camera turned by 360/N degrees about the up "
                       "axis each time (2: front and back) (default: %(default)s)")
    group.add_argument("--size", type=_picture_size, default=(1600, 1000), metavar="WxH",
                       help="picture size in pixels (default: 1600x1000)")
    group.add_argument("--dpi", type=_int_at_least(10), default=150,
                       help="dots per inch: the scale of the text (default: %(default)s)")
    group.add_argument("--range", dest="value_range", type=_pair, metavar="LOW,HIGH",
                       help="colour limits (default: from the percentiles; signed fields symmetric about 0)")
    group.add_argument("--percentiles", type=_percentile_pair, default=(2.0, 98.0), metavar="LOW,HIGH",
                       help="robust colour range (default: 2,98)")
    group.add_argument("--cmap", metavar="NAME",
                       help="matplotlib colour map (default: coolwarm for signed fields, viridis otherwise)")
    group.add_argument("--max-points", type=_int_at_least(1), default=200_000, metavar="N",
                       help="draw a random subset of N points from larger clouds (default: %(default)s)")
    group.add_argument("--point-size", type=_positive_float, metavar="PIXELS",
                       help="disc diameter (default: from the point spacing, so the surface looks closed)")
    group.add_argument("--view", type=_point3, metavar="X,Y,Z",
                       help="direction from the cloud towards the camera (default: the cloud's "
                       "thinnest direction, on the side its normals face)")
    group.add_argument("--up", type=_point3, metavar="X,Y,Z",
                       help="direction shown up (default: +y, or +z for LAS/LAZ, unless the camera looks along it)")
    group.add_argument("--elevation", type=_float, default=0.0, metavar="DEGREES",
                       help="tilt the camera up by this angle, -90..90 (default: %(default)s)")
    group.add_argument("--title", help="figure title (default: the field and the file name)")
    group.add_argument("--unit", default="length", metavar="NAME",
                       help="length unit for the colour-bar label, e.g. m gives 1/m (default: %(default)s)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``heatcurv`` command."""
    from .io import SUPPORTED_READ, SUPPORTED_WRITE

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
        "  heatcurv demo\n\n"
        "Run 'heatcurv COMMAND --help' for a command's options.",
        formatter_class=_Formatter,
    )
    parser.add_argument("--version", action="version", version=f"heatcurv {__version__}")
    _add_global_options(parser, suppress=False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    def add(name, help_text, description, epilog=None):
        command = sub.add_parser(name, help=help_text, description=description, epilog=epilog,
                                 formatter_class=_Formatter)
        return command

    # compute
    compute = add(
        "compute", "compute curvature fields of a point-cloud file and write them out",
        "Read a point cloud, estimate normals, mean, Gaussian and principal curvatures and "
        "directions and per-point areas, and write them with the input's own properties as "
        "scalar fields named nx ny nz mean gaussian k1 k2 d1x d1y d1z d2x d2y d2z area reliable "
        "(with --features also feature feature_score), which CloudCompare and MeshLab show "
        "as scalar fields. The output format follows the extension; the file is written only "
        "once everything is computed.",
        epilog=f"input formats:  {read_exts}\noutput formats: {write_exts}\n\n"
        "Curvature is in 1/(input length unit), area in (input length unit)^2; a sphere of "
        "radius R\nwith outward normals has mean = k1 = k2 = +1/R. 'reliable' is 0 where a value "
        "is not to be\ntrusted (too few neighbours, border of an open scan, ill-posed fit).\n\n"
        "example:\n  heatcurv compute scan.laz -o scan_curvature.laz --viewpoint 0,0,1.8 -j 4",
    )
    compute.add_argument("input", help="point-cloud file")
    compute.add_argument("-o", "--output", required=True, help=f"output file ({write_exts})")
    compute.add_argument("--fields", type=_field_list, metavar="LIST",
                         help="comma-separated fields to write (names above, or normals, d1, d2, "
                         "curvatures, features, border, spacing, neighbours, all) "
                         "(default: all but border, spacing, neighbours)")
    compute.add_argument("--features", action="store_true",
                         help="also detect sharp features: fields feature (0/1) and feature_score (degrees)")
    compute.add_argument("--feature-threshold", type=_float, metavar="DEGREES",
                         help="turning angle above which a point is a feature (default: automatic)")
    _add_estimate_options(compute)
    _add_global_options(compute, suppress=True)
    compute.set_defaults(run=_compute)

    # render
    render = add(
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
    render.add_argument("input", help="point-cloud file")
    render.add_argument("-o", "--output", required=True, help="picture file (.png, .pdf, .svg, .jpg, ...)")
    render.add_argument("--field", default="mean",
                        help="field to colour by: mean, gaussian, k1, k2, area, feature, feature_score, "
                        "nx, ..., or any per-point property of the file (default: %(default)s)")
    render.add_argument("--recompute", action="store_true",
                        help="compute the field even if the file holds one of that name")
    render.add_argument("--feature-threshold", type=_float, metavar="DEGREES",
                        help="threshold of --field feature (default: automatic)")
    _add_picture_options(render)
    _add_estimate_options(render)
    _add_global_options(render, suppress=True)
    render.set_defaults(run=_render)

    # features
    features = add(
        "features", "detect sharp features (creases, corners) and write mask and score",
        "Estimate the heat-kernel mean curvature and turn it into a feature score, the turning "
        "angle of the surface around each point in degrees; points above the threshold "
        "(automatic by default: Otsu's split, at least --min-angle) are features. Writes the "
        "fields feature (0/1) and feature_score next to the input's own properties.",
        epilog=f"output formats: {write_exts}\n\nexample:\n  heatcurv features part.ply -o part_features.ply",
    )
    features.add_argument("input", help="point-cloud file")
    features.add_argument("-o", "--output", required=True, help=f"output file ({write_exts})")
    features.add_argument("--threshold", type=_float, metavar="DEGREES",
                          help="turning angle above which a point is a feature (default: automatic)")
    features.add_argument("--min-angle", type=_float, default=10.0, metavar="DEGREES",
                          help="floor of the automatic threshold (default: %(default)s)")
    _add_estimate_options(features)
    _add_global_options(features, suppress=True)
    features.set_defaults(run=_features)

    # info
    info = add(
        "info", "describe a point-cloud file: points, bounding box, spacing, fields",
        "Print the number of points (and of distinct points), the bounding box, the median "
        "spacing (nearest-neighbour and 8th-neighbour distances) and the fields the file holds.",
        epilog=f"formats: {read_exts}",
    )
    info.add_argument("input", help="point-cloud file")
    _add_global_options(info, suppress=True)
    info.set_defaults(run=_info)

    # demo
    demo = add(
        "demo", "run on a built-in example: errors against exact values and a picture",
        "Sample an analytic surface, estimate its curvature with the default and the paper's "
        "method, print the errors against the exact values and draw the mean curvature. With "
        "--bunny: compute and draw the curvature of the Stanford bunny scan shipped with heatcurv.",
    )
    demo.add_argument("--surface", default="torus", choices=sorted(surfaces.SURFACES), help="surface (default: the paper's torus)")
    demo.add_argument("-n", type=int, default=20000, help="number of points (default: %(default)s)")
    demo.add_argument("--sampler", default="random", choices=surfaces.SAMPLERS, help="sampler (default random: area-uniform, irregular like a scan)")
    demo.add_argument("--noise", type=float, default=0.0, help="Gaussian noise, fraction of the bounding-box diagonal")
    demo.add_argument("--seed", type=int, default=0, help="random seed")
    demo.add_argument("--bunny", action="store_true", help="the real Stanford bunny scan instead of an analytic surface")
    demo.add_argument("-o", "--output", metavar="PICTURE",
                      help="picture of the mean curvature (default: heatcurv_demo.png, with --bunny "
                      "heatcurv_bunny.png, in the current directory)")
    demo.add_argument("--no-picture", action="store_true", help="do not draw the picture")
    _add_global_options(demo, suppress=True)
    demo.set_defaults(run=_demo)
    return parser


# ----------------------------------------------------------------------------- shared steps


def _check_output_path(path, extensions, what: str) -> Path:
    """Fail early (before any computation) on an output the writer would refuse."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in extensions:
        raise HeatcurvError(
            f"cannot write {path}: unknown {what} extension {ext or '(none)'!r}; supported: {' '.join(extensions)}"
        )
    if not path.parent.is_dir():
        raise HeatcurvError(f"cannot write {path}: the directory {path.parent} does not exist")
    if path.is_dir():
        raise HeatcurvError(f"cannot write {path}: it is a directory")
    return path


def _estimate_options(args) -> dict:
    """The keyword arguments of :func:`heatcurv.estimate` from the command line, validated."""
    from .pipeline import resolve_options

    options = {
        "method": args.method, "alpha": args.alpha, "m": args.m, "spacing": args.spacing,
        "gamma": args.gamma, "k_local": args.k_local, "neighbors": args.neighbors,
        "area_method": args.area_method, "mean_formula": args.mean_formula, "fit": args.fit,
        "scale": args.scale, "area_solver": args.area_solver, "min_neighbors": args.min_neighbors,
        "workers": args.workers,
    }
    resolve_options(**options)  # bad values fail now, not after reading a big file
    options["viewpoint"] = getattr(args, "viewpoint", None)
    return options


def _read(path, log: _Log):
    from .io import read_points

    tic = time.perf_counter()
    cloud = read_points(path)
    extras = []
    if cloud.normals is not None:
        extras.append("normals")
    if cloud.colors is not None:
        extras.append("colours")
    if cloud.fields:
        extras.append(f"{len(cloud.fields)} other field(s)")
    log.info(f"read {path}: {len(cloud)} points ({(cloud.format or '?').upper()}"
             f"{', ' + ', '.join(extras) if extras else ''})")
    log.detail(f"  reading took {time.perf_counter() - tic:.2f} s")
    return cloud


def _finite_rows(cloud, skip_nonfinite: bool) -> np.ndarray | None:
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


def _input_normals(cloud, use: bool, rows):
    if not use:
        return None
    if cloud.normals is None:
        raise HeatcurvError(
            f"{cloud.path} has no normals (nx ny nz); drop --normals-from-input to estimate them"
        )
    return cloud.normals if rows is None else cloud.normals[rows]


def _run_estimate(points, normals, options: dict, log: _Log, source=None):
    """:func:`heatcurv.estimate` with a progress bar on a terminal, and the messages around it.

    A :class:`HeatcurvError` (too few points, collinear points, ...) is
    re-raised with the name of the ``source`` file in front.
    """
    from .estimator import estimate

    progress = StageProgress(enabled=not log.quiet and sys.stderr.isatty())
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
    kernel = f", kernel {scale['fit']}" if scale else ""
    log.info(
        f"estimated curvature in {seconds:.2f} s (method {res.options.method}{kernel}): "
        f"{int(res.reliable.sum())} of {len(res)} points reliable"
    )
    if log.verbose:
        timings = res.info.get("timings", {})
        log.detail("  stage timings:")
        for stage, value in timings.items():
            log.detail(f"    {stage:<12s} {value:8.3f} s")
        log.detail(f"    {'total':<12s} {sum(timings.values()):8.3f} s")
        if scale:
            log.detail(
                f"  chord-fit kernel: {scale['fit']} ({scale['k']} neighbours, ball radius "
                f"{scale['radius']:.4g} (99th percentile), median spacing h {scale['median_h']:.4g}); "
                f"noise sigma {scale['sigma']:.3g} ({scale['relative_noise']:.3g} h)"
            )
        solve = res.info.get("area_solve")
        if res.options.area_method == "system" and solve is not None:
            log.detail(f"  area system H A = 1: {solve.solver}, {solve.iterations} iterations, "
                       f"residual {solve.residual:.2e}")
        n_distinct = res.info.get("n_distinct")
        if n_distinct is not None and n_distinct != len(res):
            log.detail(f"  {len(res) - n_distinct} duplicate point(s) share their twin's values")
    return res


def _full_rows(values: np.ndarray, rows, n: int) -> np.ndarray:
    """``values`` of the computed rows spread to all ``n`` rows (NaN, or False, elsewhere)."""
    values = np.asarray(values)
    if rows is None:
        return values
    fill = False if values.dtype.kind == "b" else np.nan
    dtype = values.dtype if values.dtype.kind in "bf" else np.float64
    full = np.full((n,) + values.shape[1:], fill, dtype=dtype)
    full[rows] = values
    return full


def _computed_values(res, feat, name: str) -> np.ndarray:
    """Field ``name`` (one of :data:`COMPUTED_FIELDS`) of a result, on the computed rows."""
    if name in FEATURE_FIELDS:
        return feat.mask if name == "feature" else feat.score
    if name in ("nx", "ny", "nz"):
        return res.normals[:, "xyz".index(name[1])]
    if name[:2] in ("d1", "d2"):
        return getattr(res, name[:2])[:, "xyz".index(name[2])]
    return getattr(res, name)


def _result_fields(res, feat, wanted, rows, n: int) -> tuple[dict, np.ndarray | None]:
    """The arrays to write, ``(fields, normals)``, for :func:`heatcurv.io.write_points`.

    Fields come in the order of :data:`COMPUTED_FIELDS`; a complete triple
    ``d1x d1y d1z`` is passed as one (n, 3) field ``d1`` (NPZ keeps it as one
    array, the other formats expand it to the same three names). Rows not
    computed (``rows``) get NaN, or 0 in masks.
    """
    wanted = set(wanted)
    normals = _full_rows(res.normals, rows, n) if "nx" in wanted else None
    fields = {}
    for name in COMPUTED_FIELDS:
        if name not in wanted or name in ("nx", "ny", "nz"):
            continue
        vector = name[:2] if name[:2] in ("d1", "d2") else None
        if vector is not None and {vector + a for a in "xyz"} <= wanted:
            if vector not in fields:
                fields[vector] = _full_rows(getattr(res, vector), rows, n)
            continue
        fields[name] = _full_rows(_computed_values(res, feat, name), rows, n)
    return fields, normals


def _write(path, cloud, fields: dict, normals, log: _Log) -> None:
    from .io import write_points

    tic = time.perf_counter()
    write_points(path, cloud.points, fields, normals=normals, source=cloud)
    names = []
    for name, values in fields.items():
        names += [name + a for a in "xyz"] if np.ndim(values) == 2 else [name]
    if normals is not None:
        names = ["nx", "ny", "nz"] + names
    log.info(f"wrote {path}: {len(cloud)} points, fields {' '.join(names)}")
    log.detail(f"  writing took {time.perf_counter() - tic:.2f} s")


# ----------------------------------------------------------------------------- commands


def _compute(args, log: _Log) -> int:
    output = _check_output_path(args.output, _supported_write(), "output")
    wanted = args.fields or DEFAULT_FIELDS + (FEATURE_FIELDS if args.features else ())
    want_features = bool(set(wanted) & set(FEATURE_FIELDS))
    options = _estimate_options(args)
    cloud = _read(args.input, log)
    rows = _finite_rows(cloud, args.skip_nonfinite)
    points = cloud.points if rows is None else cloud.points[rows]
    normals = _input_normals(cloud, args.normals_from_input, rows)
    res = _run_estimate(points, normals, options, log, source=args.input)
    feat = _detect_features(res, args.feature_threshold, 10.0, log) if want_features else None
    fields, out_normals = _result_fields(res, feat, wanted, rows, len(cloud))
    _write(output, cloud, fields, out_normals, log)
    return EXIT_OK


def _detect_features(res, threshold, min_angle, log: _Log):
    from .features import sharp_features

    feat = sharp_features(res, threshold=threshold, min_angle=min_angle)
    count = int(feat.mask.sum())
    log.info(f"sharp features: {count} of {len(res)} points ({100.0 * count / max(len(res), 1):.1f} %) "
             f"turn by more than {feat.threshold:.1f} degrees")
    return feat


def _features(args, log: _Log) -> int:
    output = _check_output_path(args.output, _supported_write(), "output")
    options = _estimate_options(args)
    cloud = _read(args.input, log)
    rows = _finite_rows(cloud, args.skip_nonfinite)
    points = cloud.points if rows is None else cloud.points[rows]
    normals = _input_normals(cloud, args.normals_from_input, rows)
    res = _run_estimate(points, normals, options, log, source=args.input)
    feat = _detect_features(res, args.threshold, args.min_angle, log)
    fields, _ = _result_fields(res, feat, FEATURE_FIELDS, rows, len(cloud))
    _write(output, cloud, fields, None, log)
    return EXIT_OK


def _supported_write():
    from .io import SUPPORTED_WRITE

    return SUPPORTED_WRITE


def _field_from_file(cloud, name: str):
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
    if axis is not None and cloud.colors is not None:
        return cloud.colors[:, axis]
    return None


def _file_normals(cloud):
    if cloud.normals is not None:
        return cloud.normals
    if all(name in cloud.fields for name in ("nx", "ny", "nz")):
        return np.column_stack([cloud.fields[name] for name in ("nx", "ny", "nz")])
    return None


def _render(args, log: _Log) -> int:
    from .render import field_style, render_field, supported_picture_formats

    output = _check_output_path(args.output, supported_picture_formats(), "picture")
    if args.cmap is not None:
        import matplotlib

        if args.cmap not in matplotlib.colormaps:
            raise HeatcurvError(f"unknown colour map {args.cmap!r}; matplotlib has e.g. coolwarm, RdBu_r, viridis, magma")
    field = args.field
    if args.recompute and field not in COMPUTED_FIELDS:
        raise HeatcurvError(f"--recompute: heatcurv does not compute {field!r}; it computes {', '.join(COMPUTED_FIELDS)}")
    options = _estimate_options(args)
    cloud = _read(args.input, log)
    values = None if args.recompute else _field_from_file(cloud, field)
    camera_normals = _file_normals(cloud)
    if values is not None:
        log.info(f"field {field!r} read from {args.input}")
    elif field in COMPUTED_FIELDS:
        rows = _finite_rows(cloud, args.skip_nonfinite)
        points = cloud.points if rows is None else cloud.points[rows]
        normals = _input_normals(cloud, args.normals_from_input, rows)
        res = _run_estimate(points, normals, options, log, source=args.input)
        feat = _detect_features(res, args.feature_threshold, 10.0, log) if field in FEATURE_FIELDS else None
        values = _full_rows(_computed_values(res, feat, field), rows, len(cloud))
        camera_normals = _full_rows(res.normals, rows, len(cloud))
    else:
        present = ["x", "y", "z"] + (["nx", "ny", "nz"] if cloud.normals is not None else []) + (
            ["red", "green", "blue"] if cloud.colors is not None else []) + list(cloud.fields)
        raise HeatcurvError(
            f"{args.input} has no field {field!r} and heatcurv does not compute it; the file holds "
            f"{', '.join(present)}; heatcurv computes {', '.join(COMPUTED_FIELDS)}"
        )
    vertical = "z" if (cloud.format or "") in ("las", "laz") else "y"
    label = field_style(field).label
    title = args.title if args.title is not None else f"{label} of {Path(args.input).name}"
    tic = time.perf_counter()
    drawn = render_field(
        cloud.points, values, output, field=field, views=args.views, size=args.size, dpi=args.dpi,
        value_range=args.value_range, percentiles=args.percentiles, cmap=args.cmap,
        max_points=args.max_points, point_size=args.point_size, title=title, length_unit=args.unit,
        normals=camera_normals, view=args.view, up=args.up, vertical=vertical, elevation=args.elevation,
    )
    low, high = drawn.limits
    points = f"a random {drawn.drawn} of {drawn.total}" if drawn.drawn < drawn.total else f"{drawn.drawn}"
    colours = "no / yes" if drawn.kind == "mask" else f"{low:.4g} .. {high:.4g}"
    log.info(f"wrote {output}: {field} of {points} points, {args.views} view(s), "
             f"{drawn.size[0]}x{drawn.size[1]} pixels, colours {colours}")
    log.detail(f"  drawing took {time.perf_counter() - tic:.2f} s")
    return EXIT_OK


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


def _info(args, log: _Log) -> int:
    cloud = _read(args.input, _Log(quiet=True))
    path = Path(args.input)
    fmt = (cloud.format or "?").upper()
    if cloud.format == "ply":
        encoding = _ply_encoding(path)
        fmt += f" ({encoding})" if encoding else ""
    header = cloud.meta.get("las_header")
    if header is not None:
        fmt += f" (version {header.version}, point format {header.point_format.id})"
    lines = [("file", f"{path}  {fmt}, {_human_bytes(path.stat().st_size)}")]
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
    if cloud.normals is not None:
        length = np.linalg.norm(cloud.normals, axis=1)
        unit = "unit length" if np.allclose(length[np.isfinite(length)], 1.0, atol=1e-3) else "not unit length"
        lines.append(("normals", f"yes (nx ny nz, {unit})"))
    else:
        lines.append(("normals", "no"))
    lines.append(("colours", "yes (red green blue, 8-bit)" if cloud.colors is not None else "no"))
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
    for label, text in lines:
        print(f"{label:<13s}{text}")
    return EXIT_OK


def _demo(args, log: _Log) -> int:
    picture = None
    if not args.no_picture:
        from .render import supported_picture_formats

        default = "heatcurv_bunny.png" if args.bunny else "heatcurv_demo.png"
        picture = _check_output_path(args.output or default, supported_picture_formats(), "picture")
    if args.bunny:
        return _demo_bunny(picture, log)

    from .estimator import estimate
    from .evaluation import compare

    surface = surfaces.get(args.surface)
    sample = surface.sample(args.n, args.sampler, noise=args.noise, seed=args.seed)
    print(
        f"heatcurv {__version__} demo: {surface.name}, {len(sample.points)} points "
        f"({args.sampler} sampler, noise {args.noise:g} of the bounding-box diagonal)"
    )
    rows = []
    for method in ("default", "paper"):
        tic = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", HeatcurvWarning)
            res = estimate(sample.points, method=method)
        seconds = time.perf_counter() - tic
        for w in caught:
            print(f"note ({method}): {w.message}")
        rows.append((method, compare(sample, res), seconds, res.info.get("scale", {}), res))

    def pct(x):
        return "       -" if x != x else f"{100 * x:8.3f}"  # NaN: exact field is zero

    print()
    print("relative L1 error (%) on interior points; angles in degrees")
    print(f"{'method':8s} {'mean':>8s} {'k1':>8s} {'k2':>8s} {'gauss':>8s} {'area':>8s} {'d1':>7s} {'normal':>7s} {'orient':>7s} {'time s':>7s}")
    for method, e, seconds, _, _ in rows:
        print(
            f"{method:8s} {pct(e['rel_mean'])} {pct(e['rel_k1'])} {pct(e['rel_k2'])} {pct(e['rel_gaussian'])} "
            f"{100 * e['area']:+8.3f} {e['d1_deg']:7.3f} {e['normal_deg']:7.3f} {100 * e['orientation']:6.2f}% {seconds:7.2f}"
        )
    print()
    print("area: relative error of the total (open surfaces: biased by the border).")
    print("'paper' follows the paper literally (accurate on regular samples only); 'default' is")
    print("built for irregular, scanned and noisy clouds (density spacing and areas, chord fit at a")
    print(f"noise-adapted kernel: here {rows[0][3]['fit']}, noise estimate {rows[0][3]['sigma']:.2g}).")
    if picture is not None:
        from .render import render_field

        res = rows[0][4]
        render_field(
            sample.points, res.mean, picture, field="mean", size=(1400, 1000), normals=res.normals,
            elevation=35.0 if surface.name == "torus" else 0.0,
            title=f"heatcurv demo: mean curvature of the {surface.name}, {len(sample.points)} {args.sampler} points",
        )
        print(f"\nwrote {picture}: the mean curvature (default method)")
    return EXIT_OK


def _demo_bunny(picture, log: _Log) -> int:
    from .data import BUNNY_ATTRIBUTION, bunny_path
    from .io import read_points

    path = bunny_path()
    cloud = read_points(path)
    print(f"heatcurv {__version__} demo: a real scan, {len(cloud)} points ({path.name}, shipped with heatcurv)")
    print(f"  {BUNNY_ATTRIBUTION}")
    res = _run_estimate(cloud.points, None, {"method": "default"}, _Log(quiet=True))
    seconds = sum(res.info["timings"].values())
    scale = res.info.get("scale", {})
    print(
        f"\ncomputed in {seconds:.2f} s: kernel {scale.get('fit')} ({scale.get('k')} neighbours), "
        f"noise estimate {scale.get('sigma', float('nan')):.2g} ({scale.get('relative_noise', float('nan')):.2g} of "
        f"the spacing); {int(res.reliable.sum())} of {len(res)} points reliable"
    )
    print(f"\n{'field':10s} {'2 %':>9s} {'median':>9s} {'98 %':>9s}  unit")
    for name, unit in (("mean", "1/length"), ("gaussian", "1/length^2"), ("k1", "1/length"), ("k2", "1/length"), ("area", "length^2")):
        low, mid, high = np.percentile(getattr(res, name)[res.reliable], [2, 50, 98])
        print(f"{name:10s} {low:9.3g} {mid:9.3g} {high:9.3g}  {unit}")
    print(f"total area {res.area.sum():.4g} length^2 (the scan has holes and a cut base)")
    if picture is not None:
        from .render import render_field

        render_field(
            cloud.points, res.mean, picture, field="mean", views=2, size=(1600, 800), normals=res.normals,
            title=f"heatcurv demo: mean curvature of the Stanford bunny scan ({len(cloud)} points)",
        )
        print(f"\nwrote {picture}: the mean curvature, front and back")
    print("\nthe same from the command line:")
    print(f"  heatcurv compute {path} -o bunny_curvature.ply")
    print("  heatcurv render bunny_curvature.ply -o bunny_mean.png --field mean --views 2")
    return EXIT_OK


# ----------------------------------------------------------------------------- entry point


def _warning_printer(show_all: bool, stream):
    """``warnings.showwarning`` printing one line ``heatcurv: warning: ...``."""

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, HeatcurvWarning) or show_all:
            text = " ".join(str(message).split())
            print(f"heatcurv: warning: {text}", file=stream, flush=True)

    return show


def main(argv=None) -> int:
    """Run the ``heatcurv`` command.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 success, 2 bad input or options, 1 unexpected error
        (a bug), 130 interrupted.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    try:
        args = build_parser().parse_args(_join_negative_values(argv))
    except _UsageError as exc:
        print(f"heatcurv: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else EXIT_OK
    debug = args.debug
    if args.quiet and args.verbose:
        print("heatcurv: error: --quiet and --verbose exclude each other", file=sys.stderr)
        return EXIT_BAD_INPUT
    log = _Log(quiet=args.quiet, verbose=args.verbose)
    try:
        with warnings.catch_warnings():
            if not debug:
                warnings.showwarning = _warning_printer(args.verbose, sys.stderr)
            return args.run(args, log)
    except HeatcurvError as exc:
        if debug:
            raise
        print(f"heatcurv: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        if debug:
            raise
        print("heatcurv: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. 'heatcurv info big.ply | head'
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return EXIT_OK
    except MemoryError:
        if debug:
            raise
        print("heatcurv: error: out of memory; try a smaller cloud, or fewer --workers", file=sys.stderr)
        return EXIT_BUG
    except Exception as exc:
        if debug:
            raise
        print(
            f"heatcurv: error: unexpected {type(exc).__name__}: {_one_line(exc)} "
            "(this is a bug in heatcurv; rerun with --debug to see the traceback, and please report it)",
            file=sys.stderr,
        )
        return EXIT_BUG


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
