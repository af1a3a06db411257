"""What the test-data fetches share: their error, the cache's completion marker, checksums, the final rename."""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

#: Written last into a complete cache: its presence is what "fetched" means.
_MARKER = ".heatcurv-fetch.json"


class ScanDataUnavailable(RuntimeError):
    """The real scans could not be fetched; the message says what failed (network, pip, checksum)."""


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _occupied(target: Path, nested: re.Pattern | None = None) -> bool:
    """Whether ``target`` exists and holds anything but entries whose names ``nested`` matches."""
    if not target.exists():
        return False
    if not target.is_dir():
        return True
    return any(nested is None or not nested.fullmatch(entry.name) for entry in target.iterdir())


def _move_into_place(tree: Path, target: Path) -> None:
    """Rename the complete ``tree`` (marker written) to ``target``.

    An empty ``target`` is replaced by the rename.  A ``target`` that already
    holds a nested cache receives ``tree``'s entries one by one, the marker
    last, so that it is complete only once everything is in place.
    """
    if target.is_dir() and any(target.iterdir()):
        for entry in sorted(tree.iterdir()):
            if entry.name != _MARKER:
                os.replace(entry, target / entry.name)
        os.replace(tree / _MARKER, target / _MARKER)
        return
    if target.is_dir():
        target.rmdir()  # empty; a rename onto it would fail on some systems
    os.replace(tree, target)
