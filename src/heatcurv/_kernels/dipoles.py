"""Compiled dipole sums over a one-level grid: the winding number, its transpose and its gradient.

The unknowns of :mod:`heatcurv.orient.consistency` are one vector ``mu_j`` a
point (its area over ``4 pi`` times its unit normal). At every point ``x_i``
three sums over the others ``x_j`` at least ``width`` away (offset
``d = x_i - x_j``) are needed:

* ``A mu``, the winding number: ``sum_j -d . mu_j / |d|^3``
  (Barill et al. 2018, eq. 8);
* ``A^T s`` for a scalar ``s_j`` a point: ``sum_j d s_j / |d|^3``;
* ``G mu``, minus the winding number's gradient:
  ``sum_j mu_j / |d|^3 - 3 d (d . mu_j) / |d|^5``.

The points come sorted into the cells of a uniform grid, each cell's members
contiguous (``start``). A cell counts as one source (its summed value at its
``|value|``-weighted centre, :func:`cell_sums`) for a point farther from that
centre than ``far``; nearer cells are summed point by point.

Arrays in, arrays out: this module imports nothing from heatcurv.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import ROW_CORE, as_floats, parallel_rows

__all__ = ["WINDING", "TRANSPOSED", "GRADIENT", "cell_sums", "dipole_sums"]

#: the three sums (module docstring): ``A mu``, ``A^T s``, ``G mu``
WINDING, TRANSPOSED, GRADIENT = 0, 1, 2


def cell_sums(x, values, start) -> tuple[np.ndarray, np.ndarray]:
    """Each cell's ``|value|``-weighted centre and summed value.

    Parameters
    ----------
    x : ndarray, shape (n, 3)
        The points, sorted by cell.
    values : ndarray, shape (n, 3)
        A vector a point (a scalar in the first column, zeros in the others).
    start : ndarray, shape (cells + 1,), int
        Where each cell's points begin in ``x``.

    Returns
    -------
    centre, total : ndarray, shape (cells, 3)
        A cell whose values are all zero is centred at its points' mean.
    """
    cells = start.size - 1
    centre, total = np.zeros((cells, 3)), np.zeros((cells, 3))
    _cell_rows(0, cells, as_floats(x), as_floats(values), np.asarray(start, dtype=np.int64), centre, total)
    return centre, total


def dipole_sums(kind: int, x, values, start, far: float, width: float) -> np.ndarray:
    """One of the three sums of the module docstring at every point, shape (n, 3).

    Parameters
    ----------
    kind : int
        :data:`WINDING` (the result in the first column), :data:`TRANSPOSED` or :data:`GRADIENT`.
    x, values, start
        As for :func:`cell_sums`.
    far : float
        Distance from a cell's centre beyond which the cell counts as one source.
    width : float
        Pairs nearer than this are left out (the smoothing width).
    """
    x, values, start = as_floats(x), as_floats(values), np.asarray(start, dtype=np.int64)
    centre, total = cell_sums(x, values, start)
    out = np.zeros((x.shape[0], 3))
    parallel_rows(_sum_rows, x.shape[0], int(kind), x, values, start, (centre, total),
                  float(far) ** 2, float(width) ** 2, out)
    return out


@njit(**ROW_CORE)
def _cell_rows(row0, row1, x, values, start, centre, total):
    for c in range(row0, row1):
        weight = 0.0
        for i in range(start[c], start[c + 1]):
            size = np.sqrt(values[i, 0] ** 2 + values[i, 1] ** 2 + values[i, 2] ** 2)
            weight += size
            for k in range(3):
                total[c, k] += values[i, k]
                centre[c, k] += size * x[i, k]
        members = start[c + 1] - start[c]
        for k in range(3):
            if weight > 0.0:
                centre[c, k] /= weight
            else:
                for i in range(start[c], start[c + 1]):
                    centre[c, k] += x[i, k] / members


@njit(inline="always", fastmath=True)
def _term(kind, dx, dy, dz, d2, v0, v1, v2):
    """One source's term at the offset ``(dx, dy, dz) = x_i - x_j`` (``|.|^2 = d2``) of value ``v``."""
    d3 = np.sqrt(d2) * d2
    if kind == 0:  # WINDING
        return -(dx * v0 + dy * v1 + dz * v2) / d3, 0.0, 0.0
    if kind == 1:  # TRANSPOSED: v0 is the scalar
        return dx * v0 / d3, dy * v0 / d3, dz * v0 / d3
    dot, d5 = dx * v0 + dy * v1 + dz * v2, d3 * d2
    return v0 / d3 - 3.0 * dx * dot / d5, v1 / d3 - 3.0 * dy * dot / d5, v2 / d3 - 3.0 * dz * dot / d5


@njit(**ROW_CORE, fastmath=True)
def _sum_rows(row0, row1, kind, x, values, start, cells, far2, width2, out):
    centre, total = cells
    for i in range(row0, row1):
        a0 = a1 = a2 = 0.0
        for c in range(start.size - 1):
            dx, dy, dz = x[i, 0] - centre[c, 0], x[i, 1] - centre[c, 1], x[i, 2] - centre[c, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if d2 > far2:  # the cell as one source at its centre
                t0, t1, t2 = _term(kind, dx, dy, dz, d2, total[c, 0], total[c, 1], total[c, 2])
                a0, a1, a2 = a0 + t0, a1 + t1, a2 + t2
                continue
            for j in range(start[c], start[c + 1]):
                dx, dy, dz = x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]
                d2 = dx * dx + dy * dy + dz * dz
                if d2 >= width2:
                    t0, t1, t2 = _term(kind, dx, dy, dz, d2, values[j, 0], values[j, 1], values[j, 2])
                    a0, a1, a2 = a0 + t0, a1 + t1, a2 + t2
        out[i, 0], out[i, 1], out[i, 2] = a0, a1, a2
