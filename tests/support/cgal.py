"""Closed models for the tests: twelve animals and figures from CGAL's data directory, fetched from Debian.

CGAL's data directory holds closed triangle models of animals and figures
with thin parts (legs, ears, tails, horns, fingers): the test data of
normal orientation on closed objects, where a wrongly oriented thin part
comes out inside out.  Debian ships that directory in the package
``libcgal-demo``; :func:`fetch_cgal_meshes` downloads the pinned package
(apt-get, or Debian's pool over HTTP; SHA-256 checked), keeps twelve of its
OFF models (:data:`CGAL_MESHES`) in a cache directory and deletes the
package.  heatcurv fetches these files for the tests and does not
redistribute them.  :func:`support.scans.read_mesh` reads them.

This module uses the standard library only; :mod:`support.scans`
re-exports its public names.
"""

from __future__ import annotations

import io
import shutil
import subprocess
import tarfile
import urllib.error
import urllib.request
from pathlib import Path

from ._fetching import _MARKER, ScanDataUnavailable, cache_root, fetch_into

__all__ = ["CGAL_DEBIAN_VERSION", "CGAL_MESHES", "cgal_cache_dir", "fetch_cgal_meshes"]

#: The Debian package version of ``libcgal-demo`` that carries CGAL 5.5.1's data directory.
CGAL_DEBIAN_VERSION = "5.5.1-2"
#: The models :func:`fetch_cgal_meshes` keeps: closed triangle meshes but ``lion.off`` (205 boundary edges).
CGAL_MESHES = tuple(
    f"{name}.off"
    for name in (
        "armadillo", "bear", "bull", "camel", "cow", "dino", "diplodocus", "elephant", "elk", "homer", "lion", "man",
    )
)
#: The cache's directory name; with ``$HEATCURV_TEST_DATA`` set, inside the pymeshlab samples' directory.
_CGAL_DIRNAME = "cgal-5.5.1"
_DEB_NAME = f"libcgal-demo_{CGAL_DEBIAN_VERSION}_all.deb"
_DEB_URL = f"http://deb.debian.org/debian/pool/main/c/cgal/{_DEB_NAME}"
_DEB_SHA256 = "78b09b23d4d6d1bf15552a1060b419ab3fc09918486462faed197e5fc6ac3735"
#: The tarball of CGAL's data directory inside the package's file tree.
_DEB_DATA_TARBALL = "usr/share/doc/libcgal-dev/data.tar.gz"
_CGAL_MEMBER_PREFIX = "data/meshes/"
_TIMEOUT = 300.0


def cgal_cache_dir() -> Path:
    """Where :func:`fetch_cgal_meshes` keeps the models when given no directory.

    ``$HEATCURV_TEST_DATA/cgal-5.5.1`` if ``HEATCURV_TEST_DATA`` is set, else
    ``cgal-5.5.1`` next to the pymeshlab samples of
    :func:`support.scans.default_cache_dir`:
    ``$XDG_CACHE_HOME/heatcurv/test-data/cgal-5.5.1`` (``~/.cache`` when
    ``XDG_CACHE_HOME`` is unset).

    Returns
    -------
    pathlib.Path
    """
    return cache_root() / _CGAL_DIRNAME


def _cgal_is_complete(directory: Path) -> bool:
    return (directory / _MARKER).is_file() and all((directory / name).is_file() for name in CGAL_MESHES)


def _download_deb(dest: Path, timeout: float) -> Path:
    """Download the pinned ``libcgal-demo`` package into ``dest``; the file's path.

    ``apt-get download libcgal-demo=5.5.1-2`` (in ``dest``) first; if apt-get
    is missing, fails or does not produce the file, the package is read from
    :data:`_DEB_URL` (Debian's pool) with :mod:`urllib`.

    Raises
    ------
    ScanDataUnavailable
        Both ways failed; the message says how each did.
    """
    deb = dest / _DEB_NAME
    why_apt = None
    try:
        proc = subprocess.run(["apt-get", "download", f"libcgal-demo={CGAL_DEBIAN_VERSION}"], cwd=dest,
                              capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        why_apt = f"apt-get download timed out after {timeout:g} s"
    except OSError as exc:
        why_apt = f"cannot run apt-get: {exc}"
    else:
        if proc.returncode != 0:
            lines = [ln for ln in (proc.stderr or proc.stdout or "").strip().splitlines() if ln.strip()]
            why_apt = "apt-get download failed: " + (" | ".join(lines[-3:]) or f"exit status {proc.returncode}")
        elif not deb.is_file():
            why_apt = f"apt-get download did not produce {_DEB_NAME} (found {sorted(p.name for p in dest.iterdir())})"
    if why_apt is None:
        return deb
    for stray in dest.iterdir():  # whatever apt-get left
        if stray.is_file():
            stray.unlink()
    try:
        with urllib.request.urlopen(_DEB_URL, timeout=timeout) as response, open(deb, "wb") as out:
            shutil.copyfileobj(response, out, 1 << 20)
    except (urllib.error.URLError, OSError, TimeoutError) as exc:
        raise ScanDataUnavailable(f"{why_apt}; downloading {_DEB_URL} failed too: {exc}") from exc
    return deb


def _ar_members(data: bytes, name: str) -> dict:
    """The members of a Unix ``ar`` archive (a Debian package): name -> bytes.

    Raises
    ------
    ScanDataUnavailable
        Not an ``ar`` archive, or a truncated one.
    """
    if not data.startswith(b"!<arch>\n"):
        raise ScanDataUnavailable(f"{name} is not a Debian package (no ar archive header)")
    members = {}
    pos = 8
    while pos < len(data):
        header = data[pos:pos + 60]
        if len(header) < 60 or header[58:60] != b"`\n":
            raise ScanDataUnavailable(f"{name}: malformed ar member header at byte {pos}")
        member = header[:16].decode("ascii", errors="replace").strip().rstrip("/")
        try:
            size = int(header[48:58].decode("ascii").strip())
        except ValueError:
            raise ScanDataUnavailable(f"{name}: malformed ar member size at byte {pos}") from None
        start = pos + 60
        if start + size > len(data):
            raise ScanDataUnavailable(f"{name}: truncated ar member {member!r}")
        members[member] = data[start:start + size]
        pos = start + size + (size & 1)  # members start at even offsets
    return members


def _extract_cgal_meshes(deb: Path, dest: Path) -> list[str]:
    """Write the :data:`CGAL_MESHES` of the package's CGAL data tarball into ``dest``.

    The package is an ``ar`` archive whose ``data.tar.xz`` (or ``.gz``,
    ``.bz2``: what :mod:`tarfile` reads) holds the file tree; in it,
    ``usr/share/doc/libcgal-dev/data.tar.gz`` is CGAL's data directory, whose
    ``data/meshes/<name>.off`` members are the models.

    Returns
    -------
    list of str
        The written file names, sorted.

    Raises
    ------
    ScanDataUnavailable
        Not a Debian package, an unreadable archive, or a model missing.
    """
    members = _ar_members(deb.read_bytes(), deb.name)
    tree_name = next((m for m in members if m.startswith("data.tar")), None)
    if tree_name is None:
        raise ScanDataUnavailable(f"{deb.name} has no data.tar member (members {sorted(members)})")
    if tree_name not in ("data.tar", "data.tar.gz", "data.tar.xz", "data.tar.bz2"):
        raise ScanDataUnavailable(f"{deb.name}: {tree_name} is compressed in a way Python's tarfile cannot read")
    wanted = {_CGAL_MEMBER_PREFIX + name: name for name in CGAL_MESHES}
    written = []
    try:
        with tarfile.open(fileobj=io.BytesIO(members[tree_name]), mode="r:*") as tree:
            inner = next((m for m in tree if m.name.lstrip("./") == _DEB_DATA_TARBALL and m.isfile()), None)
            if inner is None:
                raise ScanDataUnavailable(f"{deb.name} has no {_DEB_DATA_TARBALL}")
            with tarfile.open(fileobj=tree.extractfile(inner), mode="r|gz") as data:
                for member in data:
                    name = wanted.get(member.name.removeprefix("./"))
                    if name is None or not member.isfile():
                        continue
                    with data.extractfile(member) as src, open(dest / name, "wb") as out:
                        shutil.copyfileobj(src, out, 1 << 20)
                    written.append(name)
    except (tarfile.TarError, EOFError, OSError) as exc:  # lzma/zlib errors are OSError or EOFError
        if isinstance(exc, ScanDataUnavailable):
            raise
        raise ScanDataUnavailable(f"{deb.name}: cannot read its archives: {exc}") from exc
    missing = sorted(set(CGAL_MESHES) - set(written))
    if missing:
        raise ScanDataUnavailable(f"{deb.name} lacks the CGAL models {missing}")
    return sorted(written)


def fetch_cgal_meshes(cache_dir=None, *, timeout: float = _TIMEOUT) -> Path:
    """The directory of twelve closed models from CGAL's data directory, downloading them on the first call.

    The models (:data:`CGAL_MESHES`: armadillo, bear, bull, camel, cow,
    dino, diplodocus, elephant, elk, homer, lion, man; OFF and COFF triangle
    meshes of 1 645 to 26 002 vertices) come from CGAL 5.5.1's data
    directory as Debian ships it in the package ``libcgal-demo`` 5.5.1-2
    (24 MB, checked against its SHA-256).  heatcurv fetches them for the
    tests and does not redistribute them.  The package is downloaded with
    ``apt-get download`` (or, failing that, from Debian's pool with
    :mod:`urllib`) into a temporary directory, read in Python (the ``ar``
    archive, its ``data.tar.xz``, the ``data.tar.gz`` in it), only the
    twelve ``data/meshes/*.off`` files are kept (7.9 MB in all) and
    the package is deleted; the extracted files are renamed into place with
    a completion marker, so an interrupted fetch never leaves a partial cache.

    All twelve are single components with outward-wound faces (positive
    signed volume); all but ``lion.off`` are closed (``lion.off`` has 205
    boundary edges around small holes).

    Parameters
    ----------
    cache_dir : str or os.PathLike, optional
        The directory to hold the files; default :func:`cgal_cache_dir`
        (``$HEATCURV_TEST_DATA/cgal-5.5.1``, else
        ``~/.cache/heatcurv/test-data/cgal-5.5.1``).
    timeout : float
        Seconds the download may take (apt-get, then urllib's socket timeout).

    Returns
    -------
    pathlib.Path
        ``cache_dir``, holding e.g. ``camel.off``.

    Raises
    ------
    ScanDataUnavailable
        The fetch failed (no network, apt-get and the pool download both
        failing, wrong checksum, unreadable archive, cache directory not
        writable or occupied by other files); the message says which, for a
        test to skip with.
    """
    target = Path(cache_dir).expanduser() if cache_dir is not None else cgal_cache_dir()
    record = {"package": "libcgal-demo", "version": CGAL_DEBIAN_VERSION, "deb": _DEB_NAME, "sha256": _DEB_SHA256,
              "source": f"CGAL 5.5.1 data directory ({_DEB_DATA_TARBALL} in the package)"}
    return fetch_into(target, what="CGAL models", cache_name="CGAL model", is_complete=_cgal_is_complete,
                      download=lambda directory: _download_deb(directory, timeout), sha256=_DEB_SHA256,
                      extract=_extract_cgal_meshes, record=record)
