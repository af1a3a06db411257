"""Scale choice: how wide a kernel each point gets and how its curvature is fitted.

================  ===========================================================
``kernel_check``  refuse a kernel that cannot give an answer, warn about a
                  doubtful one
``scale``         the noise level and the per-point kernel width (the
                  bias-variance choice between chord and denoised fits)
``plan``          :func:`~heatcurv.choice.plan.plan_fit`, the one place that
                  chooses the fit's form, kernel, anchors and carry
``choices``       what a run decides once for the whole cloud, so that a
                  part of it (a tile) computes as the whole would
``survey``        the cloud-wide part of the kernel choice, measured tile by
                  tile
================  ===========================================================

The top layer of the core's subpackages: it compares fits (:mod:`heatcurv.fits`) at several
scales. Every threshold it compares against is a field of :data:`heatcurv.tuning.TUNING`.
"""
