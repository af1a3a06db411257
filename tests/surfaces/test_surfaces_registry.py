"""Tests of heatcurv.surfaces.registry: SURFACES and get.
"""

from __future__ import annotations

from heatcurv import surfaces as hs


def test_registry():
    assert set(hs.SURFACES) == {
        "sphere", "ellipsoid", "torus", "paraboloid", "saddle", "arch", "plane", "cylinder",
        "folded_square",
    }
    for name, cls in hs.SURFACES.items():
        surf = hs.get(name)
        assert isinstance(surf, cls) and surf.name == name == cls.name
        assert isinstance(surf, hs.Surface)
        assert surf.closed == (name in ("sphere", "ellipsoid", "torus"))
    assert isinstance(hs.get("Folded-Square", interior_angle=120), hs.FoldedSquare)
    assert hs.get("torus", r1=0.5, r2=2.0).r1 == 0.5
    assert "Torus(r1=1.0, r2=2.3701)" == repr(hs.Torus())
