"""What the survey gives every tile: :class:`SurveyContext`, and its scratch file ``context.json``.

The context is a frozen dataclass of frozen dataclasses (the cloud's
:class:`~heatcurv.choice.choices.CloudChoices`: its frame, the kernel widths and
their sample centres, the orientation policy) and two halo widths. It is
written as JSON, not pickled: a resumed run reads back plain, typed values.
Each dataclass is written as an object naming its type (only the types of
:data:`TYPES` are read back) with its fields; an ndarray as its dtype, shape
and values. Floats go through ``repr``, which Python reads back to the same
bits (NaN and infinities included), so a resumed run computes what a run
from the start does, bit for bit.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass

import numpy as np

from ..choice.choices import CloudChoices, CloudFrame
from ..choice.scale import ScaleChoice
from ..errors import HeatcurvError
from ..fits.balls import Scale
from ..orient.orientation import AutoPolicy

__all__ = ["SurveyContext", "TYPES", "write_context", "read_context", "to_plain", "from_plain"]


@dataclass(frozen=True)
class SurveyContext:
    """The survey's choices for every tile (:func:`.compute.merge_surveys`, :func:`.compute.merge_rounds`).

    Attributes
    ----------
    choices : heatcurv.choice.choices.CloudChoices
        The frame, kernel widths and orientation policy every tile takes.
    halo : float
        A first halo for the tiles: twice the widest chosen ball plus the
        operator's ball, x :data:`.compute.HALO_MARGIN`, input units (each
        tile's certificate checks it point by point).
    support : float
        The widest chosen ball, input units.
    """

    choices: CloudChoices
    halo: float
    support: float


#: The dataclasses a context file may hold, by name.
TYPES = {cls.__name__: cls for cls in (SurveyContext, CloudChoices, CloudFrame, ScaleChoice, Scale, AutoPolicy)}


def to_plain(value):
    """``value`` as JSON-ready values: the dataclasses of :data:`TYPES`, ndarrays, numpy scalars, lists, dicts."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        name = type(value).__name__
        if TYPES.get(name) is not type(value):
            raise TypeError(f"a context cannot hold a {type(value).__qualname__}")
        return {"type": name, "fields": {f.name: to_plain(getattr(value, f.name)) for f in dataclasses.fields(value)}}
    if isinstance(value, np.ndarray):
        return {"type": "ndarray", "dtype": value.dtype.str, "shape": list(value.shape),
                "values": value.ravel().tolist()}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [to_plain(v) for v in value]
    if isinstance(value, dict):
        return {"type": "dict", "items": [[to_plain(k), to_plain(v)] for k, v in value.items()]}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"a context cannot hold a {type(value).__qualname__}")


def from_plain(data):
    """The values :func:`to_plain` wrote."""
    if isinstance(data, list):
        return [from_plain(v) for v in data]
    if not isinstance(data, dict):
        return data
    kind = data["type"]
    if kind == "ndarray":
        return np.asarray(data["values"], dtype=np.dtype(data["dtype"])).reshape(data["shape"])
    if kind == "dict":
        return {from_plain(k): from_plain(v) for k, v in data["items"]}
    return TYPES[kind](**{name: from_plain(v) for name, v in data["fields"].items()})


def write_context(path, context: SurveyContext) -> None:
    """Write ``context`` to ``path`` as JSON, atomically (a temporary file moved into place)."""
    temporary = f"{path}.{os.getpid()}.tmp"
    with open(temporary, "w") as stream:
        json.dump(to_plain(context), stream)
    os.replace(temporary, path)


def read_context(path) -> SurveyContext:
    """The context :func:`write_context` wrote to ``path``."""
    try:
        with open(path) as stream:
            context = from_plain(json.load(stream))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise HeatcurvError(f"cannot read the survey's context {path}: {exc}; delete the scratch directory to start "
                            "afresh") from None
    if not isinstance(context, SurveyContext):
        raise HeatcurvError(f"cannot read the survey's context {path}: it holds a {type(context).__name__}")
    return context
