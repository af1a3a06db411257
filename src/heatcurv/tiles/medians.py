"""Exact medians of columns too long to hold: two streaming passes over ``results.rec``.

The reliability flags compare each point with medians over the whole cloud
(:mod:`heatcurv.flags.reliability`): the median residual of each kernel width and
the median resolution. ``np.median`` would need the whole column in memory
(800 MB per 1e8 points); here a first pass counts the values of each group
in bins of their float64 bit pattern (the top 16 bits: sign, exponent and 4
bits of mantissa, 1/16 of an octave; for non-negative numbers the bit
pattern orders as the value), a second gathers the values of the bin that
holds the middle rank, which :func:`numpy.partition` then finishes. The
result is exactly ``np.median`` of the group (the mean of the two middle
values for an even count).
"""

from __future__ import annotations

import os

import numpy as np

__all__ = ["streaming_medians"]

#: Bits of the float64 pattern the first pass bins by.
BIN_BITS = 16
_SHIFT = np.uint64(64 - BIN_BITS)
#: The group of the resolution's median among the kernel widths' residual medians (:func:`apply_cloud_flags`).
RESOLUTION_GROUP = -1


def _bins(values: np.ndarray) -> np.ndarray:
    values = np.ascontiguousarray(values, dtype=np.float64) + 0.0  # -0.0 becomes 0.0: the pattern orders as the value
    return (values.view(np.uint64) >> _SHIFT).astype(np.int64)


def streaming_medians(chunks) -> dict:
    """``{group: median}`` of non-negative values given chunk by chunk.

    Parameters
    ----------
    chunks : callable
        ``chunks()`` yields ``(groups, values)`` pairs of equal-length arrays
        (int group labels, non-negative floats, infinity included; NaN is skipped), the
        same sequence each time it is called (it is called twice).

    Returns
    -------
    dict
        The exact median of each group's values (groups with no value absent).
    """
    counts: dict = {}
    for groups, values in chunks():
        ok = ~np.isnan(values)
        groups, values = groups[ok], values[ok]
        for g in np.unique(groups):
            hist = np.bincount(_bins(values[groups == g]), minlength=1 << BIN_BITS)
            counts[int(g)] = counts.get(int(g), 0) + hist
    wanted = {}
    for g, hist in counts.items():
        n = int(hist.sum())
        ranks = (n // 2,) if n % 2 else (n // 2 - 1, n // 2)
        cumulative = np.cumsum(hist)
        bins = [int(np.searchsorted(cumulative, r, side="right")) for r in ranks]
        below = [int(cumulative[b - 1]) if b else 0 for b in bins]
        wanted[g] = (bins, [r - b for r, b in zip(ranks, below)])
    gathered: dict = {g: [] for g in wanted}
    for groups, values in chunks():
        ok = ~np.isnan(values)
        groups, values = groups[ok], values[ok]
        for g, (bins, _) in wanted.items():
            mine = values[groups == g]
            gathered[g].append(mine[np.isin(_bins(mine), bins)])
    medians = {}
    for g, (bins, offsets) in wanted.items():
        values = np.concatenate(gathered[g]) if gathered[g] else np.empty(0)
        picked = []
        for b, offset in zip(bins, offsets):
            in_bin = np.sort(values[_bins(values) == b])
            picked.append(in_bin[offset])
        medians[g] = float(np.mean(picked))
    return medians


def apply_cloud_flags(results_path, count: int, finite: int, chunk: int = 1 << 20, swamped: bool = False,
                      misfit_factor: float | None = None) -> dict:
    """Add the cloud-wide reliability flags to ``results.rec`` (its ``reliable`` column holds the local ones).

    The medians (each kernel width's residual, the resolution) are taken over
    every computed, counted row (:func:`streaming_medians`), exactly as
    :func:`heatcurv.flags.reliability.cloud_flags` takes them in memory; then each
    chunk's rows whose ``reliable`` the flags turn are rewritten in place. ``finite``: the rows every tile
    together computed; fewer computed rows mean scratch files went missing. ``swamped``: the survey's
    kernel choice measured noise as thick as the operator's balls
    (:func:`heatcurv.choice.plan.noise_swamps_balls`), which the warning of a coarse cloud then names.
    ``misfit_factor``: the fit plan's (:attr:`heatcurv.choice.plan.FitPlan.misfit_factor`).

    Returns
    -------
    dict
        ``baselines`` (width -> median residual, floored) and ``resolution``.

    Raises
    ------
    HeatcurvError
        When ``results.rec`` holds fewer than ``finite`` computed rows.

    Warns
    -----
    HeatcurvWarning
        When the cloud is too coarse for its curvature (every row unreliable).
    """
    from ..errors import HeatcurvError
    from ..flags.reliability import misfits, warn_too_coarse
    from ..tuning import TUNING
    from .output import read_results, write_records

    def blocks():
        for start in range(0, count, chunk):
            block = read_results(results_path, start, min(count, start + chunk))
            yield start, block, (block["computed"] == 1) & (block["counted"] == 1)

    computed = 0

    def columns():  # each width's residuals and, as group -1 (widths are not negative), the resolution: one read
        nonlocal computed
        computed = 0  # counted in each of the two passes
        for _, block, ok in blocks():
            computed += int(np.count_nonzero(block["computed"]))
            width = block["fit_width"][ok].astype(np.int64)
            yield (np.concatenate([width, np.full(width.size, RESOLUTION_GROUP)]),
                   np.concatenate([block["misfit_residual"][ok], block["resolution_rho"][ok]]))

    medians = streaming_medians(columns)
    if computed != finite:
        raise HeatcurvError(f"{results_path} holds {computed} computed rows of {finite}: scratch files are missing; "
                            f"delete {os.path.dirname(results_path)} and run again")
    resolution = medians.pop(RESOLUTION_GROUP, 0.0)
    baselines = {k: max(v, TUNING.misfit_floor) for k, v in medians.items()}
    coarse = resolution > TUNING.resolution_limit
    if coarse:
        warn_too_coarse(resolution, stacklevel=3, swamped=swamped)
    for start, block, _ in blocks():
        width = block["fit_width"]
        for k in np.unique(width).tolist():
            baselines.setdefault(int(k), TUNING.misfit_floor)  # a width with no counted row: the floor
        local = block["reliable"] == 1
        bad = misfits(block["misfit_residual"], width, baselines, misfit_factor)
        reliable = (local & ~bad & ~coarse).astype(np.uint8)
        # only the rows the flags turn: the pages of the others are not written back
        changed = np.flatnonzero(reliable != block["reliable"])
        block["reliable"] = reliable
        write_records(results_path, block[changed], start + changed)
    return {"baselines": baselines, "resolution": resolution}
