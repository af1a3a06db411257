"""Orientation: which side of the surface every normal points to.

===============  ============================================================
``orientation``  outward (spanning tree, then the winding number), up, or
                 towards a viewpoint; ``"auto"`` picks one per cloud
``enclosure``    the winding number's patch signs and the points it
                 contradicts on a closed cloud
===============  ============================================================
"""
