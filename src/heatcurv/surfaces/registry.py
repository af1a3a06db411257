"""The ready-to-use surfaces by name."""

from __future__ import annotations

from heatcurv.errors import HeatcurvError

from .base import Surface
from .closed import Ellipsoid, Sphere, Torus
from .graphs import Arch, Paraboloid, Plane, Saddle
from .patches import Cylinder, FoldedSquare

#: Ready-to-use surfaces by name (:class:`Graph` is not listed: it needs ``f``).
SURFACES: dict[str, type[Surface]] = {
    "sphere": Sphere,
    "ellipsoid": Ellipsoid,
    "torus": Torus,
    "paraboloid": Paraboloid,
    "saddle": Saddle,
    "arch": Arch,
    "plane": Plane,
    "cylinder": Cylinder,
    "folded_square": FoldedSquare,
}


def get(name: str, **kwargs) -> Surface:
    """Construct a surface by name.

    Parameters
    ----------
    name : str
        A key of :data:`SURFACES` (case-insensitive; ``-`` and spaces count as
        ``_``).
    **kwargs
        Constructor parameters.

    Returns
    -------
    Surface

    Raises
    ------
    HeatcurvError
        For an unknown name (the message lists the known ones) or bad
        parameters.
    """
    key = str(name).strip().lower().replace("-", "_").replace(" ", "_")
    if key not in SURFACES:
        raise HeatcurvError(
            f"unknown surface {name!r}; known surfaces: {', '.join(sorted(SURFACES))}"
        )
    try:
        return SURFACES[key](**kwargs)
    except TypeError as exc:
        raise HeatcurvError(f"bad parameters for surface {key!r}: {exc}") from exc
