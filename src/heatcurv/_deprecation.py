"""Deprecated spellings of public keywords: the one helper every module uses.

Public names are British (``neighbours``, ``colours``, ``centre``); the
American spellings users type are accepted with a ``DeprecationWarning``.
"""

from __future__ import annotations

import warnings

from .errors import HeatcurvError

__all__ = ["renamed_keyword"]


def renamed_keyword(where: str, name: str, value, alias: str, alias_value, stacklevel: int = 3):
    """``value`` of keyword ``name``, or that of its deprecated alias ``alias``, warning.

    Parameters
    ----------
    where : str
        The function or class the keyword belongs to, for the messages.
    name, alias : str
        The keyword and its deprecated spelling.
    value, alias_value
        What the caller passed for each (None: not given).
    stacklevel : int, optional
        Where the warning points: 3 is the caller of the function that calls this helper.

    Raises
    ------
    HeatcurvError
        When both spellings are given.
    """
    if alias_value is None:
        return value
    if value is not None:
        raise HeatcurvError(f"{where}: give {name}= or its deprecated alias {alias}=, not both")
    warnings.warn(
        f"{where}: {alias}= is deprecated, use {name}= (British spelling)", DeprecationWarning, stacklevel=stacklevel
    )
    return alias_value
