"""Real scans for the tests: pymeshlab's sample meshes, CGAL's closed models, and a small mesh reader.

The sample meshes that pymeshlab ships for its own tests are real data of the
kinds the estimator meets: a structured-light range map of a face with its
camera (``rangemaps/face000.ply``), closed object scans (``bunny.obj``,
``bone.ply``, ``cow.obj``), a CAD-like model (``airplane.obj``, ``cube.obj``)
and a point set with normals (``chameleon.pts``).  pymeshlab is GPL-3, so
heatcurv does not ship these files: :func:`fetch_pymeshlab_samples` downloads
the pinned wheel with pip, keeps only the sample meshes in a cache directory
and deletes the wheel.

CGAL's closed models of animals and figures with thin parts, the test data
of normal orientation on closed objects, are fetched from Debian's package
``libcgal-demo`` by :func:`fetch_cgal_meshes` (:mod:`support.cgal`,
whose names this module re-exports); heatcurv does not redistribute them.

:func:`read_mesh` reads the OBJ, PLY and OFF triangle meshes into a
:class:`Mesh`, which knows its exact (piecewise linear) areas, normals,
edges, signed volume and connected components, the reference values the
tests compare estimates with; :func:`range_camera` is the viewpoint of a
VCG range map.

This module uses numpy, scipy, plyfile and the standard library only, never
the estimator: the tests judge the estimator against what it computes.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from itertools import chain
from pathlib import Path, PurePosixPath

import numpy as np
from plyfile import PlyData, PlyElementParseError

from ._fetching import _MARKER, ScanDataUnavailable, cache_root, fetch_into
from .cgal import _CGAL_DIRNAME, CGAL_DEBIAN_VERSION, CGAL_MESHES, cgal_cache_dir, fetch_cgal_meshes

__all__ = [
    "CGAL_DEBIAN_VERSION",
    "CGAL_MESHES",
    "PYMESHLAB_SAMPLES",
    "PYMESHLAB_VERSION",
    "Mesh",
    "ScanDataUnavailable",
    "cgal_cache_dir",
    "default_cache_dir",
    "fetch_cgal_meshes",
    "fetch_pymeshlab_samples",
    "range_camera",
    "read_mesh",
]

#: The pinned pymeshlab release whose wheel carries the sample meshes.
PYMESHLAB_VERSION = "2025.7.post1"
#: The files :func:`fetch_pymeshlab_samples` guarantees, relative to its directory.
PYMESHLAB_SAMPLES = (
    "airplane.obj",
    "bone.ply",
    "bunny.obj",
    "chameleon.pts",
    "cow.obj",
    "cube.obj",
    "rangemaps/face000.ply",
)
# The wheel is the same for every platform's purposes here (we only unzip it):
# one tag, one file, one checksum.
_WHEEL_TAGS = ("--python-version", "3.11", "--platform", "manylinux_2_35_x86_64")
_WHEEL_NAME = f"pymeshlab-{PYMESHLAB_VERSION}-cp311-cp311-manylinux_2_35_x86_64.whl"
_WHEEL_SHA256 = "c3c1b01f101334b14469ace3b004382cd313b80a128f551a1da77e3053f09c30"
_MEMBER_PREFIX = f"pymeshlab-{PYMESHLAB_VERSION}.data/purelib/pymeshlab/tests/sample_meshes/"
_PIP_TIMEOUT = 300.0

# The CGAL cache and its fetch's temporary directories may live inside the pymeshlab
# cache (both under $HEATCURV_TEST_DATA): the pymeshlab fetch leaves them alone.
_NESTED = re.compile(rf"\.?{re.escape(_CGAL_DIRNAME)}(\.fetch-.*)?")


# --------------------------------------------------------------------------- fetching


def default_cache_dir() -> Path:
    """Where :func:`fetch_pymeshlab_samples` keeps the samples when given no directory.

    ``$HEATCURV_TEST_DATA`` if set, else
    ``$XDG_CACHE_HOME/heatcurv/test-data/pymeshlab-<version>`` (``~/.cache`` when
    ``XDG_CACHE_HOME`` is unset).

    Returns
    -------
    pathlib.Path
    """
    root = cache_root()
    return root if os.environ.get("HEATCURV_TEST_DATA") else root / f"pymeshlab-{PYMESHLAB_VERSION}"


def _is_complete(directory: Path) -> bool:
    return (directory / _MARKER).is_file() and all((directory / name).is_file() for name in PYMESHLAB_SAMPLES)


def _download_wheel(dest: Path, timeout: float) -> Path:
    """Download the pinned pymeshlab wheel into ``dest`` with pip; the wheel's path.

    Raises
    ------
    ScanDataUnavailable
        pip missing, failing (no network, no such file) or too slow.
    """
    cmd = [
        sys.executable, "-m", "pip", "download", f"pymeshlab=={PYMESHLAB_VERSION}", "--no-deps",
        "--only-binary=:all:", *_WHEEL_TAGS, "--dest", str(dest),
        "--disable-pip-version-check", "--no-input", "--quiet",
    ]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        raise ScanDataUnavailable(
            f"pip download of pymeshlab {PYMESHLAB_VERSION} timed out after {timeout:g} s"
        ) from None
    except OSError as exc:
        raise ScanDataUnavailable(f"cannot run pip ({sys.executable} -m pip): {exc}") from exc
    if proc.returncode != 0:
        lines = [ln for ln in (proc.stderr or proc.stdout or "").strip().splitlines() if ln.strip()]
        detail = " | ".join(lines[-3:]) or f"exit status {proc.returncode}"
        raise ScanDataUnavailable(f"pip download of pymeshlab {PYMESHLAB_VERSION} failed: {detail}")
    wheel = dest / _WHEEL_NAME
    if not wheel.is_file():
        found = sorted(p.name for p in dest.iterdir())
        raise ScanDataUnavailable(f"pip download did not produce {_WHEEL_NAME} (found {found})")
    return wheel


def _extract_samples(wheel: Path, dest: Path) -> list[str]:
    """Unzip the members under the wheel's ``sample_meshes/`` into ``dest``, keeping relative paths.

    Returns
    -------
    list of str
        The extracted files, relative POSIX paths, sorted.

    Raises
    ------
    ScanDataUnavailable
        Not a zip file, or a required sample is missing from it.
    """
    written = []
    try:
        with zipfile.ZipFile(wheel) as zf:
            for info in zf.infolist():
                if info.is_dir() or not info.filename.startswith(_MEMBER_PREFIX):
                    continue
                rel = PurePosixPath(info.filename[len(_MEMBER_PREFIX):])
                if rel.is_absolute() or ".." in rel.parts or not rel.parts:
                    raise ScanDataUnavailable(f"unsafe member path in {wheel.name}: {info.filename!r}")
                target = dest.joinpath(*rel.parts)
                target.parent.mkdir(parents=True, exist_ok=True)
                with zf.open(info) as src, open(target, "wb") as out:
                    shutil.copyfileobj(src, out, 1 << 20)
                written.append(rel.as_posix())
    except zipfile.BadZipFile as exc:
        raise ScanDataUnavailable(f"{wheel.name} is not a valid wheel: {exc}") from exc
    missing = sorted(set(PYMESHLAB_SAMPLES) - set(written))
    if missing:
        raise ScanDataUnavailable(f"{wheel.name} lacks the sample meshes {missing}")
    return sorted(written)


def fetch_pymeshlab_samples(cache_dir=None, *, timeout: float = _PIP_TIMEOUT) -> Path:
    """The directory of pymeshlab's test meshes, downloading them on the first call.

    Downloads the pinned wheel ``pymeshlab==2025.7.post1`` (106 MB, checked
    against its SHA-256) with ``python -m pip download`` into a temporary
    directory, extracts ``pymeshlab/tests/sample_meshes/`` (about 12 MB: at
    least :data:`PYMESHLAB_SAMPLES`, relative paths kept), deletes the wheel
    and renames the extracted tree into place, so an interrupted fetch never
    leaves a partial cache.  pymeshlab is GPL-3: the files are fetched for
    the tests, not shipped with heatcurv.

    Parameters
    ----------
    cache_dir : str or os.PathLike, optional
        The directory to hold the files; default :func:`default_cache_dir`
        (``$HEATCURV_TEST_DATA``, else ``~/.cache/heatcurv/test-data/pymeshlab-2025.7.post1``).
    timeout : float
        Seconds pip may take.

    Returns
    -------
    pathlib.Path
        ``cache_dir``, holding e.g. ``bunny.obj`` and ``rangemaps/face000.ply``.

    Raises
    ------
    ScanDataUnavailable
        The fetch failed (no network, pip missing or failing, wrong checksum,
        cache directory not writable, or occupied by other files); the
        message says which, for a test to skip with.
    """
    target = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    record = {"package": "pymeshlab", "version": PYMESHLAB_VERSION, "wheel": _WHEEL_NAME, "sha256": _WHEEL_SHA256,
              "license": "GPL-3.0"}
    return fetch_into(target, what="pymeshlab samples", cache_name="pymeshlab sample", is_complete=_is_complete,
                      download=lambda directory: _download_wheel(directory, timeout), sha256=_WHEEL_SHA256,
                      extract=_extract_samples, record=record, nested=_NESTED)


# --------------------------------------------------------------------------- meshes


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh: the exact piecewise-linear surface of a scan.

    Attributes
    ----------
    vertices : ndarray, shape (n, 3), float64
    faces : ndarray, shape (m, 3), int64
        Vertex indices of the triangles (polygons of the file fan-triangulated).
    normals : ndarray, shape (n, 3), float64, or None
        The file's vertex normals, unit length; NaN rows for vertices the file
        gives no normal; None if the file has none.
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None

    def __post_init__(self):
        v = np.ascontiguousarray(self.vertices, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int64).reshape(-1, 3)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices must have shape (n, 3), got {v.shape}")
        if f.size and (f.min() < 0 or f.max() >= v.shape[0]):
            raise ValueError(f"face indices must lie in [0, {v.shape[0]}), got [{f.min()}, {f.max()}]")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        if self.normals is not None:
            nrm = np.asarray(self.normals, dtype=np.float64)
            if nrm.shape != v.shape:
                raise ValueError(f"normals must have the vertices' shape {v.shape}, got {nrm.shape}")
            object.__setattr__(self, "normals", nrm)

    def __len__(self) -> int:
        return int(self.vertices.shape[0])

    def _face_cross(self) -> np.ndarray:
        """``(b - a) x (c - a)`` of every face, shape (m, 3): twice the area times the unit normal."""
        a, b, c = (self.vertices[self.faces[:, k]] for k in range(3))
        return np.cross(b - a, c - a)

    def face_areas(self) -> np.ndarray:
        """Triangle areas, shape (m,)."""
        return 0.5 * np.linalg.norm(self._face_cross(), axis=1)

    @property
    def area(self) -> float:
        """Total area of the triangles."""
        return float(np.sum(self.face_areas()))

    def vertex_areas(self) -> np.ndarray:
        """Barycentric vertex areas: a third of every adjacent triangle's area, shape (n,).

        They sum to :attr:`area`; 0 for unused vertices.
        """
        third = np.repeat(self.face_areas() / 3.0, 3)
        return np.bincount(self.faces.ravel(), weights=third, minlength=len(self))

    def vertex_normals(self) -> np.ndarray:
        """Area-weighted averages of the adjacent face normals, unit, shape (n, 3).

        Oriented by the faces' winding (counter-clockwise seen from the
        normal's side); zero rows for unused vertices and where the
        adjacent normals cancel.  On a closed, consistently wound mesh they
        point outward exactly when :meth:`signed_volume` is positive;
        :meth:`outward_vertex_normals` checks that and flips them if needed.
        """
        cross = np.repeat(self._face_cross(), 3, axis=0)  # |cross| = 2 area: area weighting
        out = np.zeros((len(self), 3))
        for k in range(3):
            out[:, k] = np.bincount(self.faces.ravel(), weights=cross[:, k], minlength=len(self))
        norm = np.linalg.norm(out, axis=1)
        good = norm > 0
        out[good] /= norm[good, None]
        return out

    def outward_vertex_normals(self) -> np.ndarray:
        """:meth:`vertex_normals` turned outward: negated when :meth:`signed_volume` is negative, shape (n, 3).

        Raises
        ------
        ValueError
            The faces are not consistently wound (:attr:`consistently_wound`)
            or enclose no volume: then no single sign makes every normal
            outward.
        """
        if not self.consistently_wound:
            raise ValueError("the faces are not consistently wound: no global sign makes the normals outward")
        volume = self.signed_volume()
        if not volume != 0.0:
            raise ValueError("the mesh encloses no volume: its outside is undefined")
        normals = self.vertex_normals()
        return normals if volume > 0 else -normals

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """The undirected edges of the faces and how many faces each borders.

        Returns
        -------
        edges : ndarray of int64, shape (e, 2)
            Vertex index pairs, the smaller first, sorted.
        faces : ndarray of int64, shape (e,)
            Faces per edge: 2 inside a closed manifold surface, 1 on a
            boundary, more at a non-manifold edge.
        """
        f = self.faces
        pairs = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        edges, counts = np.unique(pairs, axis=0, return_counts=True)
        return edges.astype(np.int64), counts.astype(np.int64)

    @property
    def closed(self) -> bool:
        """Whether every edge borders exactly two faces (no boundary, no non-manifold edge)."""
        return bool(self.faces.size) and bool(np.all(self.edges()[1] == 2))

    @property
    def consistently_wound(self) -> bool:
        """Whether no directed edge occurs twice: faces sharing an edge run along it in opposite directions."""
        f = self.faces
        directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        return np.unique(directed, axis=0).shape[0] == directed.shape[0]

    def signed_volume(self) -> float:
        """The volume the faces enclose, positive when they wind counter-clockwise seen from outside.

        The sum over the faces of the signed volumes of the tetrahedra they
        span with the vertices' centroid: the enclosed volume for a closed,
        consistently wound mesh (whatever the centre); for a mesh with small
        holes, the volume closed by cones from the centroid over the holes,
        whose sign still tells outward winding from inward.
        """
        centre = self.vertices[self.used].mean(axis=0) if self.faces.size else np.zeros(3)
        a, b, c = (self.vertices[self.faces[:, k]] - centre for k in range(3))
        return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)

    @property
    def used(self) -> np.ndarray:
        """Mask of the vertices of at least one face, shape (n,), bool."""
        mask = np.zeros(len(self), dtype=bool)
        mask[self.faces.ravel()] = True
        return mask

    def components(self) -> np.ndarray:
        """Connected components of the vertices through the faces' edges.

        Returns
        -------
        ndarray of int64, shape (n,)
            Component label of every vertex, ``0 .. k-1``; an unused vertex
            is a component of its own.
        """
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        n = len(self)
        f = self.faces
        rows = np.concatenate([f[:, 0], f[:, 1]])
        cols = np.concatenate([f[:, 1], f[:, 2]])
        graph = coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n, n))
        return connected_components(graph, directed=False)[1].astype(np.int64)


def _fan(corners: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons given as one flat index array and the polygons' corner counts.

    Polygon ``i`` with ``k = counts[i] >= 3`` corners ``c_0 .. c_{k-1}`` gives
    the triangles ``(c_0, c_j, c_{j+1})``, ``j = 1 .. k-2``.

    Parameters
    ----------
    corners : ndarray of int64, shape (sum(counts),)
    counts : ndarray of int64, shape (p,)

    Returns
    -------
    ndarray of int64, shape (sum(counts - 2), 3)
    """
    if np.all(counts == 3):
        return corners.reshape(-1, 3)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    ntri = counts - 2
    first = np.repeat(start, ntri)
    tri_start = np.concatenate([[0], np.cumsum(ntri)[:-1]])
    j = np.arange(int(ntri.sum())) - np.repeat(tri_start, ntri) + 1
    return np.column_stack([corners[first], corners[first + j], corners[first + j + 1]])


def _resolve(index: np.ndarray, before: np.ndarray | None, size: int, what: str, path: Path) -> np.ndarray:
    """OBJ indices (1-based, negative = relative to the ``before`` entries defined so far) to 0-based."""
    if np.any(index == 0):
        raise ValueError(f"{path}: {what} index 0 in a face (OBJ indices start at 1)")
    out = index - 1
    neg = index < 0
    if np.any(neg):
        out[neg] = before[neg] + index[neg]
    bad = np.flatnonzero((out < 0) | (out >= size))
    if bad.size:
        raise ValueError(f"{path}: a face refers to {what} {int(index[bad[0]])}, but the file has {size}")
    return out


def _line_starts(text: str, keyword: str) -> np.ndarray:
    """Offsets of the lines starting with ``keyword`` in the normalised OBJ text, shape (k,)."""
    return np.array([m.start() for m in re.finditer(rf"\n{keyword}[ \t]", text)], dtype=np.int64)


def _face_corners(tokens: str, corners: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertex and normal indices of the OBJ face corners ``a``, ``a/b``, ``a//c``, ``a/b/c`` in ``tokens``.

    Returns
    -------
    vertex : ndarray of int64, shape (corners,)
    normal : ndarray of int64, shape (corners,), or None
        None unless every corner names a normal.
    """
    slashes = tokens.count("/")
    if slashes == 0:
        return np.array(tokens.split(), dtype=np.int64), None
    if slashes == 2 * corners and tokens.count("//") == corners:  # every corner a//c (MeshLab)
        table = np.array(tokens.replace("//", " ").split(), dtype=np.int64).reshape(corners, 2)
        return table[:, 0], table[:, 1]
    if slashes == 2 * corners and "//" not in tokens:  # every corner a/b/c
        table = np.array(tokens.replace("/", " ").split(), dtype=np.int64).reshape(corners, 3)
        return table[:, 0], table[:, 2]
    vertex = np.array(re.sub(r"/\S*", "", tokens).split(), dtype=np.int64)  # mixed layouts
    normal = re.findall(r"(?:^| )[^ /]+/[^ /]*/([^ /]+)", tokens)
    return vertex, (np.array(normal, dtype=np.int64) if len(normal) == corners else None)


def _read_obj(path: Path) -> Mesh:
    # every line after a "\n" and unindented: patterns starting with "\n" are found fastest
    text = "\n" + re.sub(r"\n[ \t]+", "\n", path.read_bytes().decode("utf-8", errors="replace").lstrip(" \t"))
    number = r"(\S+)"
    vtx = re.findall(rf"\nv[ \t]+{number}[ \t]+{number}[ \t]+{number}", text)
    nrm = re.findall(rf"\nvn[ \t]+{number}[ \t]+{number}[ \t]+{number}", text)
    face_lines = re.findall(r"\nf[ \t]+([^\n#]*)", text)
    if not vtx:
        raise ValueError(f"{path}: no vertices ('v' lines)")
    if len(vtx) != text.count("\nv ") + text.count("\nv\t"):
        raise ValueError(f"{path}: a 'v' line with fewer than 3 numbers")
    try:
        vertices = np.array(vtx, dtype=np.float64)
        vn = np.array(nrm, dtype=np.float64).reshape(-1, 3)
    except ValueError as exc:
        raise ValueError(f"{path}: unreadable 'v' or 'vn' line: {exc}") from None
    rows = [line.split() for line in face_lines]  # parsing: one split per face line
    counts = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    if np.any(counts < 3):
        raise ValueError(f"{path}: a face with fewer than 3 corners")
    try:
        vidx, nidx = _face_corners(" ".join(chain.from_iterable(rows)), int(counts.sum()))
    except ValueError as exc:
        raise ValueError(f"{path}: unreadable 'f' line: {exc}") from None
    before_v = before_n = None
    if vidx.size and (vidx.min() < 0 or (nidx is not None and nidx.min() < 0)):
        f_starts = np.repeat(_line_starts(text, "f"), counts)
        before_v = np.searchsorted(_line_starts(text, "v"), f_starts)
        before_n = np.searchsorted(_line_starts(text, "vn"), f_starts)
    vidx = _resolve(vidx, before_v, vertices.shape[0], "vertex", path)
    normals = None
    if nidx is not None:
        nidx = _resolve(nidx, before_n, vn.shape[0], "normal", path)
        with np.errstate(invalid="ignore", divide="ignore"):  # a zero vn gives a NaN row
            unit = vn[nidx] / np.linalg.norm(vn[nidx], axis=1)[:, None]
        acc = np.zeros_like(vertices)
        for k in range(3):
            acc[:, k] = np.bincount(vidx, weights=unit[:, k], minlength=vertices.shape[0])
        norm = np.linalg.norm(acc, axis=1)
        normals = np.full_like(vertices, np.nan)
        good = norm > 0
        normals[good] = acc[good] / norm[good, None]
    return Mesh(vertices, _fan(vidx, counts), normals)


_FACE_LISTS = ("vertex_indices", "vertex_index")


def _read_plydata(path: Path) -> PlyData:
    """The PLY file; triangles by plyfile's fast fixed-length read (it checks every list's length)."""
    try:
        return PlyData.read(str(path), known_list_len={"face": dict.fromkeys(_FACE_LISTS, 3)})
    except PlyElementParseError:
        return PlyData.read(str(path))  # polygons: the general read, about 50 times slower


def _read_ply(path: Path) -> Mesh:
    ply = _read_plydata(path)
    names = [e.name for e in ply.elements]
    if "vertex" not in names:
        raise ValueError(f"{path}: no 'vertex' element")
    vert = ply["vertex"].data
    vertices = np.column_stack([np.asarray(vert[c], dtype=np.float64) for c in "xyz"])
    normals = None
    if all(c in vert.dtype.names for c in ("nx", "ny", "nz")):
        raw = np.column_stack([np.asarray(vert[c], dtype=np.float64) for c in ("nx", "ny", "nz")])
        norm = np.linalg.norm(raw, axis=1)
        normals = np.full_like(raw, np.nan)
        normals[norm > 0] = raw[norm > 0] / norm[norm > 0, None]
    faces = np.zeros((0, 3), dtype=np.int64)
    if "face" in names:
        data = ply["face"].data
        prop = next((p for p in _FACE_LISTS if p in data.dtype.names), None)
        if prop is None:
            raise ValueError(f"{path}: the 'face' element has no vertex_indices or vertex_index list")
        lists = data[prop]
        if lists.dtype != object:  # the fixed-length read: shape (m, 3)
            faces = np.asarray(lists, dtype=np.int64).reshape(-1, 3)
        elif lists.size:
            counts = np.fromiter(map(len, lists), dtype=np.int64, count=lists.size)
            if np.any(counts < 3):
                raise ValueError(f"{path}: a face with fewer than 3 corners")
            faces = _fan(np.concatenate(lists).astype(np.int64), counts)
    return Mesh(vertices, faces, normals)


def _read_off(path: Path) -> Mesh:
    """An ASCII OFF or COFF triangle mesh: vertices ``x y z`` (colours after them ignored), faces ``3 i j k``."""
    rows = [ln.split("#", 1)[0].split() for ln in path.read_bytes().decode("utf-8", errors="replace").splitlines()]
    rows = [r for r in rows if r]
    if not rows:
        raise ValueError(f"{path}: empty file, not an OFF mesh")
    keyword, *counts = rows[0]
    if keyword not in ("OFF", "COFF"):
        what = "an OFF variant" if keyword.endswith("OFF") else "not an OFF file"
        raise ValueError(f"{path}: first word {keyword!r}: {what}; read_mesh reads ASCII OFF and COFF only")
    body = 1
    if not counts:  # the counts on a line of their own
        counts = rows[1] if len(rows) > 1 else []
        body = 2
    if "BINARY" in counts:
        raise ValueError(f"{path}: binary OFF is not supported")
    if len(counts) < 2 or not all(re.fullmatch(r"\d+", c) for c in counts[:3]):
        raise ValueError(f"{path}: the OFF header needs the vertex and face counts, got {' '.join(counts)!r}")
    n_vertices, n_faces = int(counts[0]), int(counts[1])
    have = len(rows) - body
    if have < n_vertices + n_faces:
        raise ValueError(
            f"{path}: truncated: the header announces {n_vertices} vertices and {n_faces} faces, "
            f"the file has {have} lines after it"
        )
    vertex_rows = rows[body:body + n_vertices]
    face_rows = rows[body + n_vertices:body + n_vertices + n_faces]
    short = next((k for k, r in enumerate(vertex_rows) if len(r) < 3), None)
    if short is not None:
        raise ValueError(f"{path}: vertex {short} has {len(vertex_rows[short])} numbers, expected x y z")
    try:
        vertices = np.array([r[:3] for r in vertex_rows], dtype=np.float64).reshape(-1, 3)
    except ValueError as exc:
        raise ValueError(f"{path}: unreadable vertex line: {exc}") from None
    bad = next((k for k, r in enumerate(face_rows) if r[0] != "3" or len(r) < 4), None)
    if bad is not None:
        row = face_rows[bad]
        raise ValueError(
            f"{path}: face {bad} is {' '.join(row[:8])!r}; read_mesh reads OFF triangle meshes only "
            "(every face '3 i j k')"
        )
    try:
        faces = np.array([r[1:4] for r in face_rows], dtype=np.int64).reshape(-1, 3)
    except ValueError as exc:
        raise ValueError(f"{path}: unreadable face line: {exc}") from None
    out = np.flatnonzero((faces < 0) | (faces >= n_vertices))
    if out.size:
        raise ValueError(f"{path}: a face refers to vertex {int(faces.flat[out[0]])}, but the file has {n_vertices}")
    return Mesh(vertices, faces)


def read_mesh(path) -> Mesh:
    """Read a triangle or polygon mesh from an OBJ, PLY or OFF file.

    OBJ: ``v`` (the first three numbers), ``vn`` and ``f`` lines; face corners
    may be ``a``, ``a/b``, ``a//c`` or ``a/b/c``, indices 1-based or negative
    (relative to the end of the list so far); polygons are fan-triangulated.
    A vertex's normal is the average of the unit ``vn`` its face corners
    name.  PLY (ASCII or binary, via plyfile): the ``vertex`` element's
    ``x y z`` (and ``nx ny nz``), the ``face`` element's ``vertex_indices`` or
    ``vertex_index`` list; other elements (a range map's ``camera``) are
    ignored.  OFF (ASCII ``OFF`` or ``COFF``, ``#`` comments): the header's
    vertex and face counts, then as many vertex lines (``x y z``, colours
    after them ignored) and triangle lines (``3 i j k``, 0-based, colours
    after them ignored); polygons, ``NOFF``/``STOFF``/``4OFF`` and binary
    OFF are refused.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        Unknown extension or malformed file (the message names the file).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".obj":
        return _read_obj(path)
    if suffix == ".ply":
        return _read_ply(path)
    if suffix == ".off":
        return _read_off(path)
    raise ValueError(f"{path}: read_mesh reads .obj, .ply and .off files, not {suffix or 'files without extension'}")


def range_camera(path) -> np.ndarray:
    """The viewpoint of a VCG range map: its PLY ``camera`` element's ``view_p``.

    VCG (MeshLab) stores a range map's shot in the vertices' own frame, so
    ``(view_px, view_py, view_pz)`` is the scanner position among the
    vertices, on the side their normals point to.  On pymeshlab's
    ``rangemaps/face000.ply`` (a 640 x 480 range image of a face, z from
    -884 to -756, looked at along -z) the face-winding normals of all
    used vertices face ``view_p = (0, 0, 21.6)``.  That point is not quite
    the projection centre: the vertices fall on the pixel grid (to 0.01
    pixel, with the file's focal length and pixel size) when projected from
    about ``(0, 0, 5.3)``, 16 units nearer; the ray directions differ by less
    than 0.15 degrees, which does not matter for orienting normals.

    Parameters
    ----------
    path : str or os.PathLike
        A PLY file with a ``camera`` element (``view_px``, ``view_py``, ``view_pz``).

    Returns
    -------
    ndarray, shape (3,)

    Raises
    ------
    ValueError
        The file has no such camera element.
    """
    path = Path(path)
    ply = _read_plydata(path)
    if "camera" not in [e.name for e in ply.elements]:
        raise ValueError(f"{path}: no 'camera' element (not a VCG range map)")
    cam = ply["camera"].data
    if cam.size == 0 or not all(c in cam.dtype.names for c in ("view_px", "view_py", "view_pz")):
        raise ValueError(f"{path}: the 'camera' element has no view_px, view_py, view_pz")
    return np.array([float(cam[c][0]) for c in ("view_px", "view_py", "view_pz")])
