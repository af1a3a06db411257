"""Parameter samplers: regular grid, jittered grid, Fibonacci lattice, area-uniform random.

:class:`ParameterSamplers` is the part of :class:`~heatcurv.surfaces.Surface`
that chooses parameters ``(u, v)`` in the surface's domain (the layouts are
described in :mod:`heatcurv.surfaces`); subclasses override
:meth:`~ParameterSamplers._from_unit_square` (an area-preserving map where the
surface has one), :meth:`~ParameterSamplers._grid_uv` and
:meth:`~ParameterSamplers._jittered_uv`.  The simulated scanner is in
:mod:`heatcurv.surfaces.scan`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ._util import _cached_in, _wrap

#: Names of the supported samplers, see :meth:`Surface.sample`.
SAMPLERS = ("grid", "fibonacci", "random", "jittered", "scan")

_GOLDEN = (1.0 + math.sqrt(5.0)) / 2.0


def _fibonacci_unit(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The 2-D Fibonacci lattice ``((i + 0.5) / n, frac(i * golden))``, i < n."""
    i = np.arange(n, dtype=np.float64)
    t1 = (i + 0.5) / n
    # frac(i * golden) == frac(i * (golden - 1)); the latter keeps more digits.
    t2 = np.mod(i * (_GOLDEN - 1.0), 1.0)
    return t1, t2


def _reflect(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Reflect values that left ``[lo, hi]`` by less than its width back inside."""
    x = np.where(x < lo, 2.0 * lo - x, x)
    x = np.where(x > hi, 2.0 * hi - x, x)
    return np.clip(x, lo, hi)


class ParameterSamplers:
    """Parameter layouts of the samplers; a base class of :class:`~heatcurv.surfaces.Surface`.

    Works from what every surface defines: ``domain`` and ``periodic``, and
    :meth:`area` and :meth:`area_element` for the area-uniform rejection
    sampling.  The samplers return two float64 arrays ``u, v`` of shape (m,)
    inside the domain (periodic parameters in ``[t0, t1)``).
    """

    # -- the parameter domain ------------------------------------------------

    def _extent(self) -> tuple[float, float]:
        """Typical 3-D lengths of the domain along u and v (grid aspect)."""
        (u0, u1), (v0, v1) = self.domain
        return u1 - u0, v1 - v0

    def _map_into_domain(self, u: np.ndarray, v: np.ndarray, bounded: Callable):
        """Wrap periodic parameters; map the others by ``bounded(t, t0, t1)``."""
        out = []
        for t, (t0, t1), per in zip((u, v), self.domain, self.periodic):
            out.append(_wrap(t, t0, t1) if per else bounded(t, t0, t1))
        return out[0], out[1]

    def _clip_uv(self, u: np.ndarray, v: np.ndarray):
        """Wrap periodic parameters and clip the others into the domain (rounding)."""
        return self._map_into_domain(u, v, np.clip)

    # -- parameter samplers ------------------------------------------------

    def _grid_axes(self, n: int):
        """1-D grid axes and their spacings for about ``n`` grid points."""
        lu, lv = self._extent()
        counts = (
            int(round(math.sqrt(n * lu / lv))),
            int(round(math.sqrt(n * lv / lu))),
        )
        axes = []
        steps = []
        for k, (t0, t1), per in zip(counts, self.domain, self.periodic):
            if per:
                k = max(k, 3)
                axes.append(t0 + (t1 - t0) * np.arange(k, dtype=np.float64) / k)
                steps.append((t1 - t0) / k)
            else:
                k = max(k, 2)
                axes.append(np.linspace(t0, t1, k))
                steps.append((t1 - t0) / (k - 1))
        return axes[0], axes[1], steps[0], steps[1]

    def _grid_uv(self, n: int):
        us, vs, _, _ = self._grid_axes(n)
        uu, vv = np.meshgrid(us, vs, indexing="ij")
        return uu.ravel(), vv.ravel()

    def _into_domain(self, u: np.ndarray, v: np.ndarray):
        """Wrap periodic parameters and reflect the others back into the domain."""
        return self._map_into_domain(u, v, _reflect)

    def _jittered_uv(self, n: int, rng: np.random.Generator):
        us, vs, du, dv = self._grid_axes(n)
        uu, vv = np.meshgrid(us, vs, indexing="ij")
        uu = uu.ravel() + rng.uniform(-0.25, 0.25, uu.size) * du
        vv = vv.ravel() + rng.uniform(-0.25, 0.25, vv.size) * dv
        return self._into_domain(uu, vv)

    def _from_unit_square(self, t1: np.ndarray, t2: np.ndarray):
        """Map the unit square to the domain (area-preserving if possible).

        The generic map is linear: ``u`` from ``t1`` and ``v`` from ``t2``.
        """
        (u0, u1), (v0, v1) = self.domain
        return u0 + (u1 - u0) * t1, v0 + (v1 - v0) * t2

    def _fibonacci_uv(self, n: int):
        return self._from_unit_square(*_fibonacci_unit(n))

    @_cached_in("_cached_bound")
    def _area_element_bound(self) -> float:
        """An upper bound of ``|X_u x X_v|`` (dense grid maximum + 2 %)."""
        (u0, u1), (v0, v1) = self.domain
        uu, vv = np.meshgrid(np.linspace(u0, u1, 257), np.linspace(v0, v1, 257))
        return 1.02 * float(np.max(self.area_element(uu.ravel(), vv.ravel())))

    def _random_uv(self, n: int, rng: np.random.Generator):
        """Area-uniform rejection sampling in the parameter rectangle."""
        (u0, u1), (v0, v1) = self.domain
        bound = self._area_element_bound()
        box = (u1 - u0) * (v1 - v0)
        while True:
            acceptance = min(1.0, self.area() / (bound * box))
            us, vs = [], []
            count = 0
            restart = False
            while count < n:
                m = int(1.2 * (n - count) / acceptance) + 64
                u = rng.uniform(u0, u1, m)
                v = rng.uniform(v0, v1, m)
                w = self.area_element(u, v)
                wmax = float(np.max(w))
                if wmax > bound:  # bound was too low: enlarge it and start over
                    bound = 1.05 * wmax
                    self._cached_bound = bound
                    restart = True
                    break
                keep = rng.uniform(0.0, bound, m) < w
                us.append(u[keep])
                vs.append(v[keep])
                count += int(keep.sum())
            if not restart:
                return np.concatenate(us)[:n], np.concatenate(vs)[:n]
