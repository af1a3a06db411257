"""A winding-number orientation to measure heatcurv against: the iteration of WNNC.

Lin, Shi and Liu 2024, "Fast and Globally Consistent Normal Orientation based on the Winding Number
Normal Consistency" (ACM ToG 43(6); code at github.com/jsnln/WNNC, which needs a PyTorch extension
and is not on PyPI). This module re-implements its iteration for the benchmarks, not its code:

* the unknowns are one vector ``mu_i`` a point (its area over ``4 pi`` times its normal), starting at 0;
* ``A mu`` is the winding number at every point, ``sum_j mu_j . (x_j - x_i) / |x_j - x_i|^3``, over
  the pairs at least the smoothing width ``w`` apart; ``G mu`` minus its gradient there,
  ``sum_j mu_j / d^3 - 3 (x_i - x_j) ((x_i - x_j) . mu_j) / d^5``;
* each of ``iterations`` steps takes one steepest-descent step of ``|A mu - 1/2|^2`` (exact line
  search), then keeps each ``|mu_i|`` and turns it along ``G mu`` (the consistency step), while
  ``w`` falls linearly from the preset's widest to its narrowest;
* the points are first scaled into the box ``[-1/1.1, 1/1.1]`` along their longest side, as the
  authors' script does, and the widths are theirs: ``l0`` (0.002-0.016, noise-free uniform points),
  ``l1`` (0.01-0.04, real scans), ``l2`` (0.02-0.08, noise of 0.25 %).

The sums run over a one-level grid treecode: a cell's points count as one dipole (their summed
``mu`` at their ``|mu|``-weighted centre) when the query is farther from that centre than twice the
cell's side, the authors' criterion for their octree's nodes; nearer cells are summed point by point.
"""

from __future__ import annotations

import numba
import numpy as np

#: the authors' width presets: (narrowest, widest), in the scaled coordinates
PRESETS = {"l0": (0.002, 0.016), "l1": (0.01, 0.04), "l2": (0.02, 0.08)}
#: points a grid cell aims at
CELL_POINTS = 32
#: the three sums: ``A mu``, ``A^T s``, ``G mu``
WINDING, TRANSPOSED, CONSISTENCY = 0, 1, 2


def wnnc_normals(points: np.ndarray, preset: str = "l0", iterations: int = 40) -> np.ndarray:
    """Unit normals of ``points`` (shape (n, 3)) by the WNNC iteration, shape (n, 3), oriented outward."""
    low, high = points.min(axis=0), points.max(axis=0)
    x = (points - (low + high) / 2.0) * (2.0 / (np.max(high - low) * 1.1))
    narrow, wide = PRESETS[preset]
    grid = _Grid(x)
    mu = np.zeros_like(x)
    half = np.full(len(x), 0.5)
    for step in range(iterations):
        width = narrow + (iterations - 1 - step) / (iterations - 1) * (wide - narrow)
        residual = grid.transposed(half - grid.winding(mu, width), width)
        change = grid.winding(residual, width)
        mu = mu + residual * (np.sum(residual * residual) / max(np.sum(change * change), 1e-300))
        turned = grid.consistency(mu, width)
        turned /= np.maximum(np.linalg.norm(turned, axis=1, keepdims=True), 1e-300)
        mu = turned * np.linalg.norm(mu, axis=1, keepdims=True)
    return turned


class _Grid:
    """The points sorted into cells of a uniform grid, each cell's members contiguous."""

    def __init__(self, x: np.ndarray):
        extent = float(np.max(np.ptp(x, axis=0)))
        side = extent * (CELL_POINTS / len(x)) ** 0.5  # a surface: points per cell grow with the side squared
        key = np.floor((x - x.min(axis=0)) / side).astype(np.int64)
        flat = (key[:, 0] * (key[:, 1].max() + 1) + key[:, 1]) * (key[:, 2].max() + 1) + key[:, 2]
        self.order = np.argsort(flat, kind="stable")
        cells, self.start = np.unique(flat[self.order], return_index=True)
        self.start = np.append(self.start, len(x)).astype(np.int64)
        self.x = np.ascontiguousarray(x[self.order])
        self.side = side

    def _apply(self, kind: int, values: np.ndarray, width: float) -> np.ndarray:
        v = np.zeros((len(self.x), 3))
        v[:, : values.reshape(len(self.x), -1).shape[1]] = values[self.order].reshape(len(self.x), -1)
        centre, total = _cell_sums(self.x, v, self.start)
        out = np.empty((len(self.x), 3))
        _sums(kind, self.x, v, self.start, centre, total, 2.0 * self.side, width, out)
        result = np.empty_like(out)
        result[self.order] = out
        return result

    def winding(self, mu: np.ndarray, width: float) -> np.ndarray:
        """``A mu``: the winding number at every point, shape (n,)."""
        return self._apply(WINDING, mu, width)[:, 0]

    def transposed(self, s: np.ndarray, width: float) -> np.ndarray:
        """``A^T s``, shape (n, 3)."""
        return self._apply(TRANSPOSED, s, width)

    def consistency(self, mu: np.ndarray, width: float) -> np.ndarray:
        """``G mu``: minus the winding number's gradient at every point, shape (n, 3)."""
        return self._apply(CONSISTENCY, mu, width)


@numba.njit(cache=True)
def _cell_sums(x, v, start):  # pragma: no cover
    cells = start.size - 1
    centre = np.zeros((cells, 3))
    total = np.zeros((cells, v.shape[1]))
    for c in range(cells):
        weight = 0.0
        for i in range(start[c], start[c + 1]):
            w = 0.0
            for k in range(v.shape[1]):
                total[c, k] += v[i, k]
                w += v[i, k] * v[i, k]
            w = np.sqrt(w)
            weight += w
            for k in range(3):
                centre[c, k] += w * x[i, k]
        if weight > 0.0:
            centre[c] /= weight
        else:
            for i in range(start[c], start[c + 1]):
                centre[c] += x[i] / (start[c + 1] - start[c])
    return centre, total


@numba.njit(inline="always")
def _offset(x, i, y):  # pragma: no cover
    dx, dy, dz = x[i, 0] - y[0], x[i, 1] - y[1], x[i, 2] - y[2]
    return dx, dy, dz, dx * dx + dy * dy + dz * dz


@numba.njit(inline="always")
def _pair(kind, dx, dy, dz, d2, v0, v1, v2):  # pragma: no cover
    """One source's term at an offset ``(dx, dy, dz) = x_i - x_j`` (``|.|^2 = d2``) of value ``v``."""
    d3 = np.sqrt(d2) * d2
    if kind == WINDING:
        return -(dx * v0 + dy * v1 + dz * v2) / d3, 0.0, 0.0
    if kind == TRANSPOSED:  # v0 is the scalar
        return dx * v0 / d3, dy * v0 / d3, dz * v0 / d3
    dot, d5 = dx * v0 + dy * v1 + dz * v2, d3 * d2
    return v0 / d3 - 3.0 * dx * dot / d5, v1 / d3 - 3.0 * dy * dot / d5, v2 / d3 - 3.0 * dz * dot / d5


@numba.njit(parallel=True, cache=True)
def _sums(kind, x, v, start, centre, total, far, width, out):  # pragma: no cover
    for i in numba.prange(x.shape[0]):
        a0 = a1 = a2 = 0.0
        for c in range(start.size - 1):
            dx, dy, dz, d2 = _offset(x, i, centre[c])
            if d2 > far * far:  # the cell as one source at its centre
                t0, t1, t2 = _pair(kind, dx, dy, dz, d2, total[c, 0], total[c, 1], total[c, 2])
                a0, a1, a2 = a0 + t0, a1 + t1, a2 + t2
                continue
            for j in range(start[c], start[c + 1]):
                dx, dy, dz, d2 = _offset(x, i, x[j])
                if d2 >= width * width:
                    t0, t1, t2 = _pair(kind, dx, dy, dz, d2, v[j, 0], v[j, 1], v[j, 2])
                    a0, a1, a2 = a0 + t0, a1 + t1, a2 + t2
        out[i, 0], out[i, 1], out[i, 2] = a0, a1, a2
