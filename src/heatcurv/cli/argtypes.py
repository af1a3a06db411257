"""argparse ``type=`` functions: each turns one command-line word into a value or a one-line error."""

from __future__ import annotations

import argparse
import math
import re

__all__ = [
    "numbers", "point3", "pair", "percentile_pair", "picture_size", "int_at_least", "positive_float", "finite_float",
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


def int_at_least(minimum: int):
    """A type: an integer ``>= minimum``."""

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


def positive_float(text: str) -> float:
    """A finite number ``> 0``."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def finite_float(text: str) -> float:
    """A finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value
