"""The comparison harness of tiled runs: a tiled output against the in-memory result, field by field.

The acceptance measure: on a cloud forced into tiles, every field equals the
in-memory result to ``1e-6`` relative on at least 99.99 % of the points.
:func:`compare_fields` measures that share per field;
:func:`tiled_agreement` reads a tiled output file and compares it with a
:class:`~heatcurv.results.CurvatureResult` computed in memory. The tests call
them with the tolerances the current tiles reach (tests/tiles/); tightening
those is the measure of the per-tile context work.

Relative error of a value ``a`` against the in-memory ``b``:
``|a - b| / max(|b|, floor)``, ``floor`` the field's median ``|b|`` times
``1e-3`` (a curvature crossing zero has no relative error of its own). The
directions ``d1 d2`` are compared up to their sign (arbitrary, and any
tangent pair at umbilic points: such points are where they may disagree).
Masks and counts are compared exactly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["compare_fields", "tiled_agreement", "result_columns", "VECTOR_FIELDS", "EXACT_FIELDS"]

#: Fields written as three columns ``x y z``.
VECTOR_FIELDS = ("normals", "d1", "d2")
#: Fields compared exactly.
EXACT_FIELDS = ("reliable", "outlier", "border", "neighbours")


def result_columns(res) -> dict:
    """The fields of an in-memory result by the names a tiled run uses (``normals``, ``d1`` ...)."""
    names = ("normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "area", "reliable", "outlier", "border",
             "spacing", "neighbours", "fit_radius", "mean_se", "k1_se", "k2_se", "gaussian_se", "normal_se")
    return {name: np.asarray(getattr(res, name)) for name in names if getattr(res, name, None) is not None}


def compare_fields(tiled: dict, memory: dict, rtol: float = 1e-6) -> dict:
    """Per field, the share of points where the tiled value equals the in-memory one within ``rtol``.

    Parameters
    ----------
    tiled, memory : dict of str to ndarray, shape (n,) or (n, 3)
        The same fields, rows in the same order.
    rtol : float
        Relative tolerance (see the module notes).

    Returns
    -------
    dict of str to dict
        Per field: ``share`` (of points that agree), ``bad`` (their count),
        ``worst`` (largest relative error; masks: 1 where they differ).
    """
    out = {}
    for name, b in memory.items():
        if name not in tiled:
            continue
        a, b = np.asarray(tiled[name], dtype=float), np.asarray(b, dtype=float)
        if name in EXACT_FIELDS:
            err = (a != b).astype(float)
            ok = err == 0
        elif name in VECTOR_FIELDS:
            sign = np.where(np.einsum("ij,ij->i", a, b) < 0, -1.0, 1.0) if name != "normals" else 1.0
            err = np.linalg.norm(a - np.reshape(sign, (-1, 1)) * b, axis=1)
            ok = err <= rtol
        else:
            floor = max(float(np.median(np.abs(b[np.isfinite(b)]))) * 1e-3, np.finfo(float).tiny) if b.size else 1.0
            with np.errstate(invalid="ignore"):  # inf - inf: equal infinities (a point without a fit) agree
                err = np.where(a == b, 0.0, np.abs(a - b) / np.maximum(np.abs(b), floor))
            ok = err <= rtol
        ok &= np.isfinite(err)
        out[name] = {"share": float(ok.mean()) if ok.size else 1.0, "bad": int((~ok).sum()),
                     "worst": float(np.nanmax(err)) if err.size else 0.0}
    return out


def tiled_agreement(path, res, rtol: float = 1e-6) -> dict:
    """Read a tiled output (any format :func:`heatcurv.io.read_points` reads) and compare it with ``res``.

    The written values are float32 unless the run wrote float64: compare with
    ``rtol`` above float32's 6e-8 in that case.
    """
    from heatcurv.io import read_points

    cloud = read_points(path)
    fields = dict(cloud.fields)
    tiled = {}
    if cloud.normals is not None:
        tiled["normals"] = cloud.normals
    for name in ("d1", "d2"):
        if all(f"{name}{a}" in fields for a in "xyz"):
            tiled[name] = np.column_stack([fields[f"{name}{a}"] for a in "xyz"])
    for name in ("mean", "gaussian", "k1", "k2", "area", "reliable", "outlier", "border", "spacing",
                 "neighbours", "fit_radius", "mean_se", "k1_se", "k2_se", "gaussian_se", "normal_se"):
        if name in fields:
            tiled[name] = fields[name]
    return compare_fields(tiled, result_columns(res), rtol)
