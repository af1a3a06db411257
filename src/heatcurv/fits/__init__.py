"""Curvature fits: from an operator and oriented normals to mean and principal curvatures.

==================  =========================================================
``mean_curvature``  the mean-curvature normal and its sign (eqs 2.10-2.12)
``principal``       the paper's curvature-tensor fit (section 3)
``chordfit``        the default estimator's edge-chord fit, per point
``anchors``         the same fit at anchors with wide kernels, carried to
                    every point
==================  =========================================================

Which of them runs, with which kernel, is decided in :mod:`heatcurv.choice`.
"""
