"""The estimator's flags (``--method``, ``--alpha``, ...) and the :func:`heatcurv.estimate` keywords they give.

:func:`add_estimator_options` adds the group "curvature estimation" to a
command's parser; :func:`estimator_kwargs` turns the parsed arguments into the
keywords of :func:`heatcurv.estimate`, validated before any file is read. Each
flag's default is None: the ``--method`` preset's value (:data:`heatcurv.options.METHODS`).

The flags keep their American spelling (``--neighbors``, ``--min-neighbors``);
they give the :class:`heatcurv.options.Options` fields ``neighbours`` and
``min_neighbours``.
"""

from __future__ import annotations

import argparse

from ..options import METHODS, resolve_options
from .argtypes import finite_float, int_at_least, point3, positive_float

__all__ = ["add_estimator_options", "estimator_kwargs"]


def _workers(text: str) -> int:
    """``-j``: -1 (all cores) or a thread count."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value == 0 or value < -1:
        raise argparse.ArgumentTypeError(f"expected -1 (all cores) or a thread count >= 1, got {value}")
    return value


def _kernel_scale(text: str):
    """``--scale``: ``auto`` or a neighbour count >= 20."""
    if text == "auto":
        return "auto"
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'auto' or a neighbour count, got {text!r}") from None
    if value < 20:
        raise argparse.ArgumentTypeError(f"a neighbour count must be at least 20, got {value}")
    return value


def add_estimator_options(parser, *, viewpoint: bool = True) -> None:
    """Add the options of :func:`heatcurv.estimate` to ``parser``; None means the method's value.

    With ``viewpoint`` also ``--viewpoint`` and ``--normals-from-input``
    (exclusive); always ``-j/--workers`` and ``--skip-nonfinite``.
    """
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
    group.add_argument("--alpha", type=positive_float, metavar="A",
                       help=f"ball radius in units of the spacing, r = alpha h {presets('alpha')}")
    group.add_argument("--m", type=positive_float, metavar="M",
                       help=f"diffusion time t = m h^2 {presets('m')}")
    group.add_argument("--spacing", choices=("global", "local", "density"),
                       help=f"spacing h: eq 2.6, eq 2.7 or from the density {presets('spacing')}")
    group.add_argument("--gamma", type=finite_float, metavar="G",
                       help=f"blend of eq 2.7, in [0, 1] {presets('gamma')}")
    group.add_argument("--k-local", type=int_at_least(2), metavar="K",
                       help=f"neighbours of eq 2.7's min/max {presets('k_local')}")
    group.add_argument("--neighbors", type=int_at_least(20), metavar="K",
                       help="neighbours in the density ball, and the narrowest chord-fit kernel "
                       f"{presets('neighbours')}")
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
    group.add_argument("--min-neighbors", type=int_at_least(3), metavar="K",
                       help=f"fewest neighbours per point {presets('min_neighbours')}")
    if viewpoint:
        normals = group.add_mutually_exclusive_group()
        normals.add_argument("--viewpoint", type=point3, metavar="X,Y,Z",
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


def estimator_kwargs(args) -> dict:
    """The keyword arguments of :func:`heatcurv.estimate` from the parsed command line, validated.

    Raises
    ------
    HeatcurvError
        On a bad combination of values (e.g. ``--gamma 2``): before a big file is read.
    """
    options = {
        "method": args.method, "alpha": args.alpha, "m": args.m, "spacing": args.spacing,
        "gamma": args.gamma, "k_local": args.k_local, "neighbours": args.neighbors,
        "area_method": args.area_method, "mean_formula": args.mean_formula, "fit": args.fit,
        "scale": args.scale, "area_solver": args.area_solver, "min_neighbours": args.min_neighbors,
        "workers": args.workers,
    }
    resolve_options(**options)  # bad values fail now, not after reading a big file
    options["viewpoint"] = getattr(args, "viewpoint", None)
    return options
