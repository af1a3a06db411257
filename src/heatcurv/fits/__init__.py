"""Curvature fits: from oriented normals and a neighbourhood to principal curvatures and directions.

==============  =============================================================
``principal``   the paper's curvature-tensor fit (section 3)
``chordfit``    the default estimator's edge-chord fit, per point
``balls``       the chord fit at one kernel width (:class:`~heatcurv.fits.balls.Scale`),
                every centre with its whole ball, block by block
``anchors``     the same fit at anchors with wide kernels, carried to every point
``uncertainty`` standard errors of the fitted values: noise and bias
==============  =============================================================

Which of them runs, with which kernel, is decided in :mod:`heatcurv.choice`;
:mod:`heatcurv.fit_stages` runs them as the estimator's stages.
"""
