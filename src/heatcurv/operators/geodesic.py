"""Geodesic distance on a point cloud by the heat method (Crane, Weischedel and Wardetzky 2013).

Distance is read off heat: after a short time ``t`` the heat ``u`` from a
point source falls off along geodesics from it, so ``X = -grad u / |grad u|``
is the unit field along which the distance grows; the distance is the
function whose gradient is closest to ``X``, the solution of the Poisson
problem ``-Delta phi = -div X``. Three steps, all on the pair weights ``W_ij``
of the first-order stiffness ``S1 = diag(W 1) - W`` of
:class:`~heatcurv.operators.point_laplacian.PointCloudLaplacian`:

1. **Heat.** One backward Euler step ``(diag(A) + t S1) u = delta_s``
   (``delta_s = 1/A_s`` at the sources), ``t = HEAT_TIME * s^2`` with ``s``
   the mean spacing ``sqrt(mean A)``. ``S1`` has positive pair weights, so
   ``u`` is positive and falls off monotonically; the heat of the
   second-order operator ``L1 + gamma L1^2`` does not (its far field
   changes sign, and its gradient points anywhere).
2. **Gradient.** At each point the weighted least-squares slope in its
   tangent plane: with ``d_ij = x_j - x_i``,
   ``grad u_i = M_i^+ sum_j W_ij (u_j - u_i) d_ij``, ``M_i = sum_j W_ij d_ij d_ij^T``,
   the pseudo-inverse taken over ``M_i``'s two largest eigenvectors (the
   tangent plane; the third is the normal). Exact on linear functions.
3. **Divergence and Poisson.** The weak divergence of ``X`` against the same
   pair energy, ``b_i = sum_j W_ij (X_i + X_j) / 2 . (x_i - x_j) g_ij``: the
   trapezoid rule for the rise of the distance from ``x_j`` to ``x_i``, along
   the arc over the surface rather than the chord, ``g_ij = 1 + (h_i^2 +
   h_j^2) / (12 |x_i - x_j|^2)`` with ``h`` each point's height over the
   other's tangent plane (the arc over a quadric to third order, as for the
   ring below). On a plane ``g_ij = 1`` and ``b`` is the adjoint of the pair
   differences: for a linear ``phi`` with gradient ``X``, ``S1 phi = b``
   exactly, on any sampling. ``(S1 + eps diag(A)) phi = b`` (``eps`` tiny:
   ``b`` sums to 0 over every connected piece, so the shift only fixes the
   constant).

Where two fronts of heat meet (a cut locus: the far side of a torus's tube,
behind a bump), their slopes cancel in the least-squares gradient, and its
unit direction, along the ridge between them, is not the distance's: the
distance has a kink there, whose weak gradient is the mean of the two
slopes, shorter than 1. So ``X_i`` is shortened to ``r_i X_i`` where the
heat's relative slope ``r_i = |grad u_i| / u_i`` over its pair-weighted mean
on the row is under :data:`CUT_RATIO` (near 1 elsewhere: on a random sphere,
which has no such line, 99 % of the points lie above 0.84) and beyond the
sampling's own spread of it (:data:`CUT_SPREADS`), outside the ring (near
the source the heat falls by orders of magnitude across a ball, and the
ratio is unsteady).

The constant is fixed last. The heat method rounds the distance's cone at
the source over a few spacings, so ``phi`` at the source itself sits above
the cone's apex and pinning ``phi(source) = 0`` would shorten every distance
by that much (1.4 spacings on a random sphere). Instead ``phi`` is shifted to
match the distance near the source over the ring of points :data:`RING`
spacings from it, the chord ``c`` lengthened by the curvature along it
(:meth:`HeatGeodesics.near_distance`: ``c + h^2 / (6 c)``, ``h`` the height
over the source's tangent plane, the geodesic over a quadric to third
order), at the points where the quadric can hold (under :data:`FLAT_SLOPE`
of a chord high: not across a thin part or round a bend); inside the ring,
where the heat's distance is rounded, that is the distance (where the heat's
distance agrees that the point is near: under twice the ring's inner
radius).

The heat of a short step falls off by a constant factor per spacing, so on
a large cloud it can fall below the floating-point range far from the
source, where its gradient is lost: the step is then lengthened (four times,
refactorised) until the heat stays above :data:`HEAT_FLOOR` everywhere the
source reaches. Points in a connected piece of the cloud without a source
(no pair weight joins them to one) are at infinite distance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .._kernels import laplacian as lap_kernels
from ..errors import HeatcurvError

__all__ = ["HeatGeodesics", "HEAT_TIME", "RING", "HEAT_FLOOR", "FLAT_SLOPE", "CUT_RATIO", "CUT_SPREADS"]

#: Heat time in squared mean spacings: longer steps smooth the distance over a torus's cut locus, shorter
#: ones lose the sphere (the choice is measured in docs/laplacian.md).
HEAT_TIME = 0.1
#: Inner and outer radius, in mean spacings, of the ring around each source that fixes the constant.
RING = (8.0, 16.0)
#: Fewest ring points; a smaller ring is widened to this many nearest points.
RING_POINTS = 16
#: Least heat at a reachable point before the step is lengthened (about 1e58 above the smallest double).
HEAT_FLOOR = 1e-250
#: Most times the heat step is lengthened (each four times).
LONGER_STEPS = 8
#: Most height over the source's tangent plane, per unit of chord, at which its quadric gives the distance.
FLAT_SLOPE = 0.3
#: A point beyond the ring whose relative heat slope ``|grad u| / u`` is under this share of its row's mean, and
#: further under 1 than :data:`CUT_SPREADS` robust standard deviations of that ratio, is on a cut locus.
CUT_RATIO = 0.6
#: See :data:`CUT_RATIO`: the sampling's own spread of the ratio (wider on a sparser operator) is not a cut locus.
CUT_SPREADS = 7.0


@dataclass
class HeatGeodesics:
    """The heat method's precomputed pieces for one cloud: factorisations and the tangent gradient.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        The cloud, input units.
    area : ndarray, shape (n,)
        Per-point areas (the lumped mass), input units squared.
    first_order : scipy.sparse.csr_matrix, shape (n, n)
        The first-order stiffness ``S1 = diag(W 1) - W`` (symmetric, rows summing to 0).
    factor : callable
        ``factor(matrix)`` returns an object whose ``solve(b)`` solves with a
        symmetric positive definite sparse ``matrix``.

    Attributes
    ----------
    time : float
        The heat time ``t``, input units squared (longer than ``HEAT_TIME s^2``
        when the heat fell below :data:`HEAT_FLOOR`).
    spacing : float
        The mean spacing ``s = sqrt(mean(area))``, input units.
    piece : ndarray, shape (n,), int
        The connected piece of the pair-weight graph each point is in.
    """

    points: np.ndarray
    area: np.ndarray
    first_order: sp.csr_matrix
    factor: object = field(repr=False)
    time: float = field(init=False)
    spacing: float = field(init=False)
    piece: np.ndarray = field(init=False, repr=False)
    _weights: sp.csr_matrix = field(init=False, repr=False)
    _row_weight: np.ndarray = field(init=False, repr=False)
    _arc_weights: np.ndarray = field(init=False, repr=False)
    _slope: np.ndarray = field(init=False, repr=False)
    _normal: np.ndarray = field(init=False, repr=False)
    _heat: object = field(init=False, repr=False)
    _poisson: object = field(init=False, repr=False)

    def __post_init__(self):
        S1 = self.first_order.tocsr()
        W = (sp.diags(S1.diagonal()) - S1).tocsr()  # the pair weights, zero diagonal
        W.eliminate_zeros()
        self._weights = W
        moment = lap_kernels.pair_second_moments(self.points, W.indptr, W.indices, W.data)
        value, vector = np.linalg.eigh(moment)  # ascending: the last two span the tangent plane
        if not np.all(value[:, 1] > 1e-12 * value[:, 2]):
            raise HeatcurvError("a point's neighbours lie on a line: it has no tangent plane for a geodesic gradient")
        self._normal = vector[:, :, 0]
        self._row_weight = np.asarray(W.sum(axis=1)).ravel()
        self._arc_weights = W.data * lap_kernels.arc_over_chord(self.points, W.indptr, W.indices, self._normal)
        tangent = vector[:, :, 1:]
        self._slope = np.einsum("nik,nk,njk->nij", tangent, 1.0 / value[:, 1:], tangent)  # M_i^+, shape (n, 3, 3)
        self.piece = csgraph.connected_components(W, directed=False)[1]
        self.spacing = float(np.sqrt(self.area.mean()))
        self.time = HEAT_TIME * self.spacing**2
        self._heat = self._heat_factor()
        shift = 1e-9 * float(np.median(S1.diagonal() / self.area))
        self._poisson = self.factor(S1 + shift * sp.diags(self.area))

    def _heat_factor(self):
        """The factorised backward Euler matrix ``diag(A) + t S1`` of the current heat time."""
        return self.factor(sp.diags(self.area) + self.time * self.first_order)

    def gradient(self, u: np.ndarray) -> np.ndarray:
        """Tangent gradient of a field ``u``, shape (n,) -> (n, 3): ``M_i^+ sum_j W_ij (u_j - u_i) d_ij`` (step 2)."""
        W = self._weights
        return lap_kernels.tangent_gradient(self.points, W.indptr, W.indices, W.data, self._slope, u)

    def divergence(self, field: np.ndarray) -> np.ndarray:
        """Weak divergence of a tangent field along the surface, shape (n, 3) -> (n,) (step 3).

        ``b_i = sum_j W_ij (X_i + X_j) / 2 . (x_i - x_j) g_ij``, ``g_ij`` the arc over the chord.
        """
        W = self._weights
        return lap_kernels.weak_divergence(self.points, W.indptr, W.indices, self._arc_weights, field)

    def directions(self, u: np.ndarray, near: np.ndarray) -> np.ndarray:
        """The unit field along which the distance grows, shape (n,) -> (n, 3), shortened on cut loci.

        ``-grad u / |grad u|`` (step 2); 0 where the heat is 0 (a piece the
        sources do not reach). Beyond the ring (``near``, shape (n,): the
        distance to the nearest source over its quadric, :meth:`near_distance`),
        times the relative slope ``r_i`` (module docstring) where it is under
        both :data:`CUT_RATIO` and ``1 - CUT_SPREADS s``, ``s`` the ratio's
        robust standard deviation over the cloud.
        """
        grad = self.gradient(u)
        # far from the source the heat and its gradient are tiny (1e-200): squaring them would underflow
        largest = np.abs(grad).max(axis=1)
        scaled = -grad / np.where(largest > 0, largest, 1.0)[:, None]
        length = np.linalg.norm(scaled, axis=1)  # largest component 1: in [1, sqrt 3], or 0
        unit = scaled / np.maximum(length, 1.0)[:, None]
        heated = u > 0
        if not heated.any():
            return unit
        slope = np.zeros(u.size)
        slope[heated] = length[heated] * (largest[heated] / u[heated])  # |grad u| / u
        mean = (self._weights @ slope) / self._row_weight
        ratio = np.divide(slope, mean, out=np.ones(u.size), where=mean > 0)
        reached = ratio[heated]
        spread = 1.4826 * np.median(np.abs(reached - np.median(reached)))
        cut = (ratio < min(CUT_RATIO, 1.0 - CUT_SPREADS * spread)) & (near > RING[1] * self.spacing)
        return unit * np.where(cut, ratio, 1.0)[:, None]

    def heat(self, sources: np.ndarray) -> np.ndarray:
        """The heat ``u`` of one backward Euler step from the sources, shape (n,) (step 1).

        Lengthens the step while the heat at a point the sources reach is
        below :data:`HEAT_FLOOR` (module docstring).
        """
        delta = np.zeros(self.area.size)
        delta[sources] = 1.0  # delta_s = 1/A_s, times the mass
        reached = np.isin(self.piece, self.piece[sources])
        for _ in range(LONGER_STEPS + 1):
            u = self._heat.solve(delta)
            if np.all(u[reached] > HEAT_FLOOR):
                return u
            self.time *= 4.0
            self._heat = self._heat_factor()
        raise HeatcurvError("the heat from the sources falls below the floating-point range even after a step "
                            f"{4**LONGER_STEPS} times longer: the cloud is too long and thin for the heat method")

    def near_distance(self, sources: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The geodesic distance to the nearest source over a quadric through it: ``c + h^2 / (6 c)``.

        ``c`` is the chord, ``h`` the point's height over the source's tangent
        plane (its normal: the least eigenvector of ``M_s``). Over a quadric
        ``h = kappa_n c^2 / 2`` and the geodesic is ``c (1 + kappa_n^2 c^2 / 24)``
        to third order, ``kappa_n`` the normal curvature along the chord.

        Returns
        -------
        distance : ndarray, shape (n,)
        flat : ndarray, shape (n,), bool
            Where the quadric can hold: ``|h| <= FLAT_SLOPE c`` (not across a
            thin part, not round a bend).
        """
        chord, nearest = cKDTree(self.points[sources]).query(self.points)
        source = np.asarray(sources)[nearest]
        height = np.einsum("ij,ij->i", self.points - self.points[source], self._normal[source])
        distance = chord + height**2 / (6.0 * np.maximum(chord, np.finfo(float).tiny))
        return distance, np.abs(height) <= FLAT_SLOPE * chord

    def distance(self, sources: np.ndarray) -> np.ndarray:
        """Geodesic distance from the nearest of ``sources`` to every point, shape (n,), input units.

        Parameters
        ----------
        sources : ndarray, shape (s,), int
            Distinct point indices.

        Returns
        -------
        ndarray, shape (n,)
            0 at the sources, ``inf`` in the connected pieces that hold none.
        """
        near, flat = self.near_distance(sources)
        phi = self._poisson.solve(self.divergence(self.directions(self.heat(sources), near)))
        lo, hi = RING[0] * self.spacing, RING[1] * self.spacing
        distance = np.full(phi.size, np.inf)
        for piece in np.unique(self.piece[sources]):
            member = self.piece == piece
            ring = member & flat & (near >= lo) & (near <= hi)
            if ring.sum() < RING_POINTS:  # a small or coarse piece: its nearest points where the quadric holds
                usable = np.flatnonzero(member & flat)
                ring = np.zeros(near.size, dtype=bool)
                ring[usable[np.argsort(near[usable])[:RING_POINTS]]] = True
            distance[member] = phi[member] - np.median(phi[ring] - near[ring])
        # inside the ring the curved chord is the distance, where the heat's is rounded
        inside = flat & (near < lo) & (distance < 2.0 * lo)
        distance[inside] = near[inside]
        return distance
