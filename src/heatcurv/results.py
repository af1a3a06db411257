"""The result of :func:`heatcurv.estimate`: every field, one row per input point."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .options import Options

__all__ = ["CurvatureResult"]


@dataclass(frozen=True)
class CurvatureResult:
    """Differential geometry of a point cloud, one row per input point, in input order.

    Attributes
    ----------
    normals : ndarray, shape (n, 3)
        Unit normals, consistently oriented (closed surfaces: outward), or the
        caller's normals normalised.
    mean : ndarray, shape (n,)
        Signed mean curvature, 1/length; positive where the surface bends
        away from its normal (sphere, outward normals: +1/R).
    gaussian : ndarray, shape (n,)
        Gaussian curvature ``k1 * k2``, 1/length^2.
    k1, k2 : ndarray, shape (n,)
        Principal curvatures, ``k1 >= k2``.
    d1, d2 : ndarray, shape (n, 3)
        Unit principal directions, tangent, ``d1 x d2 = normals``. Their sign
        is arbitrary; at umbilic points (sphere, plane) any tangent pair.
    area : ndarray, shape (n,)
        Per-point area, length^2; the sum estimates the surface area. 0 for
        outliers and for points whose ball holds both sides of a thin part
        (:func:`heatcurv.flags.sheets.second_sheet`, ``info["second_sheet"]``).
    reliable : ndarray, shape (n,), bool
        False where the values are not to be trusted: the point's ball held
        too few neighbours (nearest neighbours were used instead), its
        neighbourhood is not surface-like (PCA planarity < 0.05), the tensor
        fit was ill-posed, its area came out non-positive (or is 0: both
        sides of a thin part in its ball), it is a border
        point, an outlier, its normal has no consistent side
        (``info["orientation"]``), the chord fit's residual is ten times the
        cloud's median (the ball holds more than one smooth surface: a sharp
        edge, vegetation), or the rounding of the coordinates (float32, a LAS
        file's scale) can move its curvature by more than 1 %
        (``info["precision"]``); everywhere if the area system did not converge or
        the cloud is too coarse for its curvature (``info["resolution"]``; a
        ``HeatcurvWarning`` says so).
    outlier : ndarray, shape (n,), bool
        Stray points and small islands that no surface at the kernel's scale
        explains (:mod:`heatcurv.flags.outliers`): area 0 (``area.sum()`` leaves
        them out), never reliable, and no weight in their neighbours' fits.
    border : ndarray, shape (n,), bool
        Points whose fit's ball is cut by the border of an open surface
        (:mod:`heatcurv.flags.border`): their values come from one-sided
        neighbourhoods. Noisy clouds are fitted with wider balls, so their
        border band is wider.
    spacing : ndarray, shape (n,)
        The spacing ``h`` of the heat kernel (``t = m h^2``; eq 2.6, 2.7, or
        ``d_k / alpha``) at each point: the kernel of the Laplace-Beltrami
        operator and of ``mean_curvature_normal``. The chord fit may use a
        wider kernel; ``info["scale"]`` (a :class:`heatcurv.choice.scale.ScaleReport`)
        says which.
    neighbours : ndarray, shape (n,), int
        Points in each heat-kernel ball (the point itself excluded).
    fit_radius : ndarray, shape (n,)
        The radius of the ball the curvatures were fitted on at each point,
        length units: the per-point scale the kernel choice made
        (:mod:`heatcurv.choice.scale`; on noisy clouds the anchors' balls carried to
        the point, :mod:`heatcurv.fits.anchors`). The paper's method: the operator's
        ball. ``info["scale"].support_radius`` bounds how far any point's
        values reach, with the cloud-wide choices fixed (:mod:`heatcurv.choice.choices`).
    mean_se, k1_se, k2_se, gaussian_se : ndarray, shape (n,) or None
        Standard errors of ``mean``, ``k1``, ``k2`` and ``gaussian``, in their
        units: the root of the noise variance propagated through the fit (the
        rounding of float32 or gridded coordinates included) and of
        the discretisation bias estimated from a refit at twice the kernel
        (:mod:`heatcurv.fits.uncertainty`; their calibration against exact
        values: docs/accuracy.md). None for ``method="paper"``, with
        ``radius=``, ``se=False`` or a part of a cloud (``choices=``).
    normal_se : ndarray, shape (n,) or None
        Standard error of the normal's direction, degrees (as the others).
    mean_curvature_normal : ndarray, shape (n, 3)
        ``K = L x`` of eq 2.10, approximately ``2 mean * normals``, with ``L``
        the heat-kernel operator of :class:`heatcurv.operators.operator.HeatKernelOperator`
        (eq 2.9 over the method's areas), *not* the default of
        :func:`heatcurv.laplacian` (:class:`heatcurv.PointCloudLaplacian`,
        whose ``mean_curvature_normal()`` gives its own; docs/laplacian.md
        compares both against ``2 H n``).
    options : Options
        The resolved options the result was computed with.
    info : dict
        ``n_distinct`` (points after merging duplicates), ``resolution`` (the
        median point's sampling spacing in radii of curvature; above
        ``TUNING.resolution_limit`` the cloud is too coarse
        and every point unreliable), ``orientation`` (a
        :class:`heatcurv.orient.orientation.OrientationReport`: the policy used and
        how many points it could not orient), ``outliers`` (their number), ``area_solve``
        (solver, iterations, residual), ``timings`` (seconds per named stage,
        :data:`heatcurv.progress.STAGES`), ``plan`` (a :class:`heatcurv.choice.plan.FitPlan`:
        the fit's form, kernel, anchors and carry, what ran), and for the chord fit
        ``scale``, a :class:`heatcurv.choice.scale.ScaleReport`: the kernel chosen (``k``
        neighbours, ``fit`` label, ``radius``: 99th percentile of its ball
        radii), the noise estimate ``sigma`` (length units) and
        ``relative_noise`` (``sigma / h``).
    """

    normals: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    area: np.ndarray
    reliable: np.ndarray
    outlier: np.ndarray
    border: np.ndarray
    spacing: np.ndarray
    neighbours: np.ndarray
    mean_curvature_normal: np.ndarray
    options: Options
    info: dict = field(default_factory=dict)
    fit_radius: np.ndarray | None = None
    mean_se: np.ndarray | None = None
    k1_se: np.ndarray | None = None
    k2_se: np.ndarray | None = None
    gaussian_se: np.ndarray | None = None
    normal_se: np.ndarray | None = None

    FIELDS = ("normals", "mean", "gaussian", "k1", "k2", "d1", "d2", "area")

    def __len__(self) -> int:
        return int(self.mean.shape[0])

    def __repr__(self) -> str:
        return (
            f"CurvatureResult(n={len(self)}, method={self.options.method!r}, "
            f"total_area={self.area.sum():.6g}, reliable={int(self.reliable.sum())}/{len(self)})"
        )

    def as_dict(self) -> dict:
        """The per-point arrays by name (``FIELDS`` plus ``reliable``)."""
        return {name: getattr(self, name) for name in self.FIELDS + ("reliable",)}
