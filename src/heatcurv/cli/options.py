"""The estimator's flags, generated from the one declaration of the options.

:func:`add_estimator_options` adds the group "curvature estimation" to a
command's parser: one flag per field of :class:`heatcurv.options.Options`
whose metadata says ``cli`` (``--alpha``, ``--spacing``, ``--neighbours`` ...),
with the field's help, choices and range check, and both presets' values in
the help. :func:`estimator_kwargs` turns the parsed arguments into the
keywords of :func:`heatcurv.estimate`, validated before any file is read. Each
flag's default is None: the ``--method`` preset's value (:data:`heatcurv.options.METHODS`).
"""

from __future__ import annotations

import argparse
from dataclasses import fields

from ..options import METHODS, Options, resolve_options
from .argtypes import finite_float, point3

#: The ``workers`` option's own check (its range in :data:`heatcurv.options.RANGES`).
_WORKERS_CHECK = next(f.metadata["check"] for f in fields(Options) if f.name == "workers")

__all__ = ["add_estimator_options", "estimator_kwargs", "option_flags"]


def _workers(text: str) -> int:
    """``-j``: -1 (all cores) or a thread count, checked as the ``workers`` option is."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    problem = _WORKERS_CHECK(value)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return value


def _parser_of(name: str, meta: dict):
    """The argparse type of option ``name``: its Python type, then the option's own check."""
    default = getattr(METHODS["default"], name)
    is_float = meta.get("type") is float or isinstance(default, float)

    def parse(text: str):
        if name == "scale" and text == "auto":
            value = "auto"
        elif is_float:
            value = finite_float(text)
        else:  # int options, and scale's neighbour count
            try:
                value = int(text)
            except ValueError:
                what = "'auto' or a neighbour count" if name == "scale" else "an integer"
                raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        problem = meta["check"](value) if meta.get("check") is not None else None
        if problem is not None:
            raise argparse.ArgumentTypeError(problem)
        return value

    parse.__name__ = name  # argparse names the type in its messages
    return parse


def option_flags() -> dict[str, list[str]]:
    """The command-line flag of each option exposed there, by option name (one flag each, in a list)."""
    return {f.name: [f"--{f.name.replace('_', '-')}"] for f in fields(Options) if f.metadata.get("cli")}


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
    for f in fields(Options):
        if not f.metadata.get("cli"):
            continue
        meta = f.metadata
        kwargs = {"dest": f.name, "help": f"{meta['help']} {presets(f.name)}"}
        if meta.get("choices") is not None:
            kwargs["choices"] = meta["choices"]
        else:
            kwargs["type"] = _parser_of(f.name, meta)
            float_option = f.metadata.get("type") is float or isinstance(getattr(METHODS["default"], f.name), float)
            kwargs["metavar"] = "auto|K" if f.name == "scale" else "X" if float_option else "K"
        group.add_argument(*option_flags()[f.name], **kwargs)
    if viewpoint:
        normals = group.add_mutually_exclusive_group()
        normals.add_argument("--viewpoint", type=point3, metavar="X,Y,Z",
                             help="orient the estimated normals towards this sensor position "
                             "(input coordinates; negative values are fine: --viewpoint -10,0,2)")
        normals.add_argument("--normals-from-input", action="store_true",
                             help="use the input file's normals (nx ny nz) instead of estimating them; "
                             "curvature signs follow them")
    group.add_argument("-j", "--workers", type=_workers, default=-1, metavar="N",
                       help="cores to use: -1 (all cores) or 1-1024; the threads of an in-memory run, or in a "
                       "tiled run at most N tiles at once sharing N cores (default: %(default)s)")
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
    options = {"method": args.method, "workers": args.workers}
    options.update({name: getattr(args, name) for name in option_flags()})
    resolve_options(**options)  # bad values fail now, not after reading a big file
    options["viewpoint"] = getattr(args, "viewpoint", None)
    return options
