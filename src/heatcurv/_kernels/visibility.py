"""Compiled ray-casting kernel: which rays leave a cloud of discs without hitting one.

Each occluder is a flat disc (centre ``c_j``, unit axis ``a_j``, radius
``r_j``); the sign of the axis does not matter. A ray ``o + t d`` (``d`` a unit
direction) hits disc ``j`` at ``t = (c_j - o) . a_j / (d . a_j)`` when that
point lies within ``r_j`` of ``c_j``. Hits at ``t <= reach`` do not count, so
that the discs around a ray's own origin do not stop it. The discs are
registered in the cells of a uniform grid (every cell their bounding box
touches) and each ray walks the cells it crosses (Amanatides and Woo 1987, "A
fast voxel traversal algorithm for ray tracing") until it hits a disc or
leaves the grid, which holds every disc and origin.

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, parallel_rows

__all__ = ["escaping_rays"]


def escaping_rays(origins, directions, reach, centres, axes, radii) -> np.ndarray:
    """How many of each origin's rays leave the grid without hitting a disc beyond ``reach``.

    Parameters
    ----------
    origins : ndarray, shape (m, 3)
    directions : ndarray, shape (m, k, 3)
        Unit directions of each origin's ``k`` rays.
    reach : float or ndarray, shape (k,)
        Hits at this distance from the origin or nearer do not count (one per ray of a fan).
    centres, axes : ndarray, shape (s, 3)
        The discs' centres and unit axes.
    radii : ndarray, shape (s,)
        The discs' radii, all positive.

    Returns
    -------
    ndarray, shape (m,), int64
        The number of rays of each origin that hit no disc.
    """
    origins, centres, radii = as_floats(origins), as_floats(centres), as_floats(radii)
    side = 2.0 * float(np.max(radii))  # a disc's bounding box touches at most two cells a side
    lo = np.minimum(origins.min(axis=0), (centres - radii[:, None]).min(axis=0)) - side
    hi = np.maximum(origins.max(axis=0), (centres + radii[:, None]).max(axis=0)) + side
    dims = np.floor((hi - lo) / side).astype(np.int64) + 1
    first = np.floor((centres - radii[:, None] - lo) / side).astype(np.int64)
    last = np.floor((centres + radii[:, None] - lo) / side).astype(np.int64)
    keys, owners = [], []
    for step in np.ndindex(2, 2, 2):
        cell = first + np.asarray(step)
        inside = np.flatnonzero(np.all(cell <= last, axis=1))
        keys.append((cell[inside, 0] * dims[1] + cell[inside, 1]) * dims[2] + cell[inside, 2])
        owners.append(inside)
    keys, owners = np.concatenate(keys), np.concatenate(owners)
    order = np.argsort(keys, kind="stable")
    keys, owners = keys[order], owners[order].astype(np.int64)
    cells, starts = np.unique(keys, return_index=True)
    starts = np.append(starts, keys.size).astype(np.int64)
    out = np.zeros(origins.shape[0], dtype=np.int64)
    grid = (as_floats(lo), float(side), dims, cells, starts, owners)
    reach = np.broadcast_to(np.asarray(reach, dtype=np.float64), directions.shape[1:2]).copy()
    parallel_rows(_escaping_rows, out.shape[0], origins, as_floats(directions), reach, grid, centres,
                  as_floats(axes), radii * radii, out)
    return out


@njit(**ROW_CORE)
def _escaping_rows(row0, row1, origins, directions, reach, grid, centres, axes, radius2, out):
    lo, side, dims, cells, starts, owners = grid
    big = 1e300
    for a in range(row0, row1):
        ox, oy, oz = origins[a, 0], origins[a, 1], origins[a, 2]
        fx, fy, fz = (ox - lo[0]) / side, (oy - lo[1]) / side, (oz - lo[2]) / side
        count = 0
        for r in range(directions.shape[1]):
            dx, dy, dz = directions[a, r, 0], directions[a, r, 1], directions[a, r, 2]
            cx, cy, cz = int(np.floor(fx)), int(np.floor(fy)), int(np.floor(fz))
            sx = 1 if dx > 0 else -1
            sy = 1 if dy > 0 else -1
            sz = 1 if dz > 0 else -1
            # the ray's length across one cell, and to the first boundary, along each axis
            tdx = side / abs(dx) if dx != 0 else big
            tdy = side / abs(dy) if dy != 0 else big
            tdz = side / abs(dz) if dz != 0 else big
            nx = ((cx + (sx > 0)) - fx) * side / dx if dx != 0 else big
            ny = ((cy + (sy > 0)) - fy) * side / dy if dy != 0 else big
            nz = ((cz + (sz > 0)) - fz) * side / dz if dz != 0 else big
            hit = False
            while 0 <= cx < dims[0] and 0 <= cy < dims[1] and 0 <= cz < dims[2]:
                key = (cx * dims[1] + cy) * dims[2] + cz
                at = np.searchsorted(cells, key)
                if at < cells.shape[0] and cells[at] == key:
                    for q in range(starts[at], starts[at + 1]):
                        j = owners[q]
                        den = dx * axes[j, 0] + dy * axes[j, 1] + dz * axes[j, 2]
                        if den == 0.0:
                            continue
                        t = ((centres[j, 0] - ox) * axes[j, 0] + (centres[j, 1] - oy) * axes[j, 1]
                             + (centres[j, 2] - oz) * axes[j, 2]) / den
                        if t <= reach[r]:
                            continue
                        hx = ox + t * dx - centres[j, 0]
                        hy = oy + t * dy - centres[j, 1]
                        hz = oz + t * dz - centres[j, 2]
                        if hx * hx + hy * hy + hz * hz <= radius2[j]:
                            hit = True
                            break
                if hit:
                    break
                if nx <= ny and nx <= nz:
                    cx += sx
                    nx += tdx
                elif ny <= nz:
                    cy += sy
                    ny += tdy
                else:
                    cz += sz
                    nz += tdz
            if not hit:
                count += 1
        out[a] = count
