"""The fields heatcurv computes, in the order ``compute`` writes them, and the shorthands of ``--fields``."""

from __future__ import annotations

import argparse
import re

__all__ = [
    "DEFAULT_FIELDS", "FEATURE_FIELDS", "EXTRA_FIELDS", "ERROR_FIELDS", "COMPUTED_FIELDS", "FIELD_GROUPS", "field_list",
    "needs_errors",
]

#: Scalar fields ``compute`` writes by default, in this order (normals as ``nx ny nz``).
DEFAULT_FIELDS = (
    "nx", "ny", "nz", "mean", "gaussian", "k1", "k2",
    "d1x", "d1y", "d1z", "d2x", "d2y", "d2z", "area", "reliable",
)
#: Fields of the sharp-feature detector.
FEATURE_FIELDS = ("feature", "feature_score")
#: Further fields ``--fields`` can ask for.
EXTRA_FIELDS = ("border", "outlier", "spacing", "neighbours", "fit_radius")
#: Standard errors of the curvatures (their units) and of the normal (degrees).
ERROR_FIELDS = ("mean_se", "gaussian_se", "k1_se", "k2_se", "normal_se")
#: Every field heatcurv computes, in the written order.
COMPUTED_FIELDS = DEFAULT_FIELDS + FEATURE_FIELDS + EXTRA_FIELDS + ERROR_FIELDS
#: Shorthands of ``--fields``.
FIELD_GROUPS = {
    "normals": ("nx", "ny", "nz"),
    "d1": ("d1x", "d1y", "d1z"),
    "d2": ("d2x", "d2y", "d2z"),
    "curvatures": ("mean", "gaussian", "k1", "k2"),
    "default": DEFAULT_FIELDS,
    "features": FEATURE_FIELDS,
    "errors": ERROR_FIELDS,
    "all": COMPUTED_FIELDS,
}


def needs_errors(fields) -> bool:
    """Whether writing or drawing ``fields`` needs the standard errors (the estimate skips them otherwise:
    they cost time and change no other field)."""
    return any(name in ERROR_FIELDS for name in fields)


def field_list(text: str) -> tuple:
    """argparse type of ``--fields``: names and shorthands -> field names in the written order.

    Any normal component brings the other two (normals are written as a triple).
    """
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
