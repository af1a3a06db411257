"""Normals and orientation: which way the surface faces at every point.

===============  ============================================================
``normals``      PCA normals of a neighbourhood, and one consistent side
``orientation``  outward (spanning tree, then the winding number), up, or
                 towards a viewpoint; ``"auto"`` picks one per cloud
``enclosure``    the winding number's patch signs and the points it
                 contradicts on a closed cloud
``consistency``  the winding field's own normals, solved from no
                 orientation: a second opinion on the sides
===============  ============================================================

Imports :mod:`heatcurv.geometry` and :mod:`heatcurv.operators` only;
:mod:`heatcurv.normal_stages` runs it as the estimator's stages.
"""
