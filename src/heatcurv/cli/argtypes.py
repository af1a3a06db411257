"""argparse ``type=`` functions: each turns one command-line word into a value or a one-line error."""

from __future__ import annotations

import argparse
import math
import re

from ..features import FEATURE_RANGES
from ..options import SEED_RANGE, Range, range_problem
from ..render import PICTURE_RANGES

__all__ = [
    "numbers", "point3", "indices", "pair", "percentile_pair", "picture_size", "finite_float", "in_range", "CLI_RANGES",
]


def numbers(text: str, count: int, what: str) -> tuple:
    """``count`` finite numbers separated by commas or spaces."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return values


def point3(text: str) -> tuple:
    """A point or direction ``X,Y,Z``."""
    return numbers(text, 3, "three numbers X,Y,Z")


def indices(text: str) -> tuple:
    """Point indices ``I[,J...]``, counted from 0."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    if not parts or not all(re.fullmatch(r"\d+", p) for p in parts):
        raise argparse.ArgumentTypeError(f"expected point indices counted from 0, like 0 or 12,40, got {text!r}")
    return tuple(int(p) for p in parts)


def pair(text: str) -> tuple:
    """A range ``LOW,HIGH`` with ``LOW < HIGH``."""
    low, high = numbers(text, 2, "two numbers LOW,HIGH")
    if not low < high:
        raise argparse.ArgumentTypeError(f"expected LOW < HIGH, got {text!r}")
    return low, high


def percentile_pair(text: str) -> tuple:
    """A range of percentiles ``LOW,HIGH`` within 0..100."""
    low, high = pair(text)
    if not (0 <= low and high <= 100):
        raise argparse.ArgumentTypeError(f"percentiles must lie in 0..100, got {text!r}")
    return low, high


def picture_size(text: str) -> tuple:
    """``WIDTHxHEIGHT`` in pixels, each 100-10000."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX*,]\s*(\d+)\s*", text)
    if not match:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels (e.g. 1600x900), got {text!r}")
    width, height = int(match[1]), int(match[2])
    if not (100 <= width <= 10000 and 100 <= height <= 10000):
        raise argparse.ArgumentTypeError(f"width and height must be 100-10000 pixels, got {text!r}")
    return width, height


def finite_float(text: str) -> float:
    """A finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


#: The documented ranges of the command line's own numeric values (the
#: estimator's are :data:`heatcurv.options.RANGES`), with the reason for each.
CLI_RANGES: dict[str, Range] = {
    **{name: PICTURE_RANGES[name] for name in ("views", "dpi", "max_points", "point_size", "elevation")},
    "threshold": FEATURE_RANGES["threshold"],
    "feature_threshold": FEATURE_RANGES["threshold"],
    "min_angle": FEATURE_RANGES["min_angle"],
    "n": Range(4, 10_000_000, True, "points of the demo's sample: the surfaces need 4; 1e7 fills gigabytes"),
    "noise": Range(0.0, 1.0, False, "a fraction of the bounding-box diagonal"),
    "seed": SEED_RANGE,
}


def in_range(name: str, limits: Range | None = None):
    """A type: a number (an integer where ``limits.integer``) in the range ``limits`` (default ``CLI_RANGES[name]``).

    The error names the value and the range, as :func:`heatcurv.options.resolve_options` does:
    ``views = 50 is outside its range [1, 36]: ...``.
    """
    limits = CLI_RANGES[name] if limits is None else limits

    def parse(text: str):
        try:
            value = int(text) if limits.integer else float(text)
        except ValueError:
            what = "an integer" if limits.integer else "a number"
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        problem = range_problem(name, value, limits)
        if problem is not None:
            raise argparse.ArgumentTypeError(problem)
        return value

    parse.__name__ = name
    return parse
