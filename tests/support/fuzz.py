"""Fuzzing the readers and the estimator: seed files, mutators, a child-process runner, campaigns.

The readers of :mod:`heatcurv.io` promise that any file either reads or fails
with one :class:`~heatcurv.errors.HeatcurvError` whose one-line message names
the file and the problem in plain words, and never crashes the interpreter,
hangs or takes memory out of proportion to the file. This module checks that
promise the way an attacker or a damaged disk would break it:

1. :func:`seed_files` writes one valid 120-point file of every format and
   variant (:data:`VARIANTS`);
2. :data:`MUTATORS` break them: each is a pure function ``(bytes, rng) ->
   bytes`` (truncations, byte flips, header counts and types, encodings, zip
   bombs, ...), applied to the variants of its format families;
3. :class:`Worker` reads each mutated file in a long-lived child process
   under an address-space limit (``RLIMIT_AS``) and a per-case timeout, and
   is restarted after a crash or a hang; :func:`classify` turns what
   happened into one of :data:`OUTCOMES`;
4. :func:`run_campaign` does all of it for ``n`` mutations per variant and
   returns a :class:`Campaign` (the outcome table, the failing cases and how
   to reproduce each one).

The same :class:`Worker` runs the property tests of :func:`heatcurv.estimate`
(``tests/fuzz``): :func:`estimate_summary` is the function it runs there.

Outcomes
--------
=================  ==========================================================
``ok``             the file was read
``error``          a HeatcurvError of one line naming the file (the promise)
``bad-message``    a HeatcurvError of several lines, or not naming the file,
                   or naming no problem in words (an opaque wrapped code
                   such as ``(35)``, ``(MemoryError)``, ``('x')``), or
                   holding control characters, or over 400 characters
``exception``      any other exception escaped :func:`heatcurv.io.read_points`
``crash``          the child died (a signal, or an exit in the middle)
``hang``           the case took longer than the timeout
``memory``         a MemoryError (anywhere in the exception chain: the reader
                   tried to allocate past the limit), or the peak resident
                   memory of the case grew by more than
                   ``MEMORY_FACTOR * file size + MEMORY_BASE``
=================  ==========================================================

Peak memory: the worker resets the kernel's high-water mark of its resident
set before each case (``/proc/self/clear_refs``, Linux 4.0 and later) and
reads it back with :func:`resource.getrusage` after it, so the peak is the
case's own. The threshold, 20 times the file plus 64 MiB (600 times for NPZ, whose
arrays may honestly inflate 200:1), is generous for an
honest reader: the 120-point seeds read with a growth of at most a few MiB
(plyfile, laspy and NumPy hold the file, its decoded columns in float64 and a
copy or two, under 10 times the file size), while a reader that trusts a
header count of 2**31, or inflates a zip bomb, takes hundreds of MiB.

Contradictions: an accepted file is also checked against what its own header
announces (the PLY ``element vertex`` count, the OFF and PTS counts, the NPY
shape, the LAS point count), and a LAS header with a zero or non-finite scale
must not be accepted. The mutators of :data:`EXACT_OR_REFUSED` change only how
a file describes its data (counts, formats, offsets, scales, the box): a file
they leave readable must read as the seed, every attribute (points, normals,
colours, faces and each field, bit for bit: :func:`attribute_digests`,
:func:`attribute_differences`). A disagreement is recorded in
:attr:`CaseResult.contradiction`.

Reproduce one case from the repository's root with ``PYTHONPATH=tests python -m
support.fuzz VARIANT MUTATOR SEED`` (it writes the mutated file and reads it
in-process, with the full traceback); each :class:`CaseResult` prints its own command.
"""

from __future__ import annotations

import re
import struct
import sys
import tempfile
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .child import MEMORY_LIMIT, TIMEOUT, Reply, Worker
from .mutators import MUTATORS, N_SEED, Mutator, header_end, mutate, npy_header

__all__ = [
    "COMPRESSED_MEMORY_FACTOR", "Campaign", "CaseResult", "FAILURES", "MEMORY_BASE", "MEMORY_FACTOR", "MEMORY_LIMIT",
    "MUTATORS", "Mutator", "N_SEED", "OUTCOMES", "Reply", "TIMEOUT", "VARIANTS", "Variant", "Worker",
    "EXACT_OR_REFUSED", "announced_points", "attribute_differences", "attribute_digests", "classify",
    "estimate_summary", "message_problem", "mutate", "mutators_for", "read_summary",
    "run_campaign", "seed_files", "warm_estimate", "REPLAY",
]

#: The command that replays one case (``VARIANT MUTATOR SEED`` follow), run from the repository's root.
REPLAY = "PYTHONPATH=tests python -m support.fuzz"

#: A case whose peak resident memory grows by more than ``MEMORY_FACTOR * size + MEMORY_BASE`` is "memory".
MEMORY_FACTOR = 20
#: The factor for compressed formats, whose honest expansion is bounded by the reader's ratio limit
#: instead: an NPZ may declare 200 bytes of arrays per byte of file (``heatcurv.io.arrays``), read
#: with at most three copies in memory.
COMPRESSED_MEMORY_FACTOR = {".npz": 3 * 200}
MEMORY_BASE = 64 * 2**20
#: Outcomes in table order; :data:`FAILURES` are those the readers must never produce.
FAILURES = ("bad-message", "exception", "crash", "hang", "memory")
OUTCOMES = ("ok", "error") + FAILURES


# ----------------------------------------------------------------------------------------------- seeds
@dataclass(frozen=True)
class Variant:
    """A seed file: its extension, format family (what mutators apply) and whether it is text."""

    ext: str
    family: str
    textual: bool


#: Every seed variant, by name.
VARIANTS = {
    "ply-binary-le": Variant(".ply", "ply", False),
    "ply-ascii-faces": Variant(".ply", "ply", True),
    "ply-binary-be-faces": Variant(".ply", "ply", False),
    "las-1.2-fmt3": Variant(".las", "las", False),
    "las-1.4-fmt6": Variant(".las", "las", False),
    "las-1.4-fmt7": Variant(".las", "las", False),
    "laz-1.2-fmt3": Variant(".laz", "laz", False),
    "laz-1.4-fmt7": Variant(".laz", "laz", False),
    "xyz": Variant(".xyz", "text", True),
    "txt": Variant(".txt", "text", True),
    "csv": Variant(".csv", "text", True),
    "csv-hand": Variant(".csv", "text", True),
    "pts": Variant(".pts", "pts", True),
    "obj": Variant(".obj", "obj", True),
    "off": Variant(".off", "off", True),
    "npy": Variant(".npy", "npy", False),
    "npz": Variant(".npz", "npz", False),
}


def _seed_cloud():
    """120 points of a torus 10 units wide, far from the origin, with normals, colours and two fields."""
    from heatcurv.surfaces import Torus

    sample = Torus().sample(N_SEED, "fibonacci")
    rng = np.random.default_rng(11)
    points = sample.points * 10.0 + np.array([1000.0, 2000.0, 50.0])
    colours = rng.integers(0, 256, (N_SEED, 3)).astype(np.uint8)
    fields = {"intensity": rng.integers(0, 4096, N_SEED).astype(np.uint16), "mean": sample.mean / 10.0}
    return points, sample.normals, colours, fields


def _faces():
    return [(i, i + 1, i + 2) for i in range(N_SEED - 2)]


def _write_plyfile(path, points, normals, colours, text, byte_order):
    import plyfile

    vertex = np.empty(N_SEED, dtype=[(n, "f4") for n in ("x", "y", "z", "nx", "ny", "nz")]
                      + [(n, "u1") for n in ("red", "green", "blue")])
    for k, axis in enumerate("xyz"):
        vertex[axis], vertex["n" + axis] = points[:, k] - 1000.0, normals[:, k]
    for k, name in enumerate(("red", "green", "blue")):
        vertex[name] = colours[:, k]
    face = np.empty(N_SEED - 2, dtype=[("vertex_indices", "O")])
    face["vertex_indices"] = [np.array(f, dtype=np.int32) for f in _faces()]
    elements = [plyfile.PlyElement.describe(vertex, "vertex"),
                plyfile.PlyElement.describe(face, "face", len_types={"vertex_indices": "u1"},
                                            val_types={"vertex_indices": "i4"})]
    plyfile.PlyData(elements, text=text, byte_order=byte_order, comments=["heatcurv fuzz seed"]).write(str(path))


def _write_laspy(path, points, colours, fields, point_format, version):
    import laspy

    header = laspy.LasHeader(point_format=point_format, version=version)
    header.scales, header.offsets = np.full(3, 1e-4), np.array([1000.0, 2000.0, 0.0])
    las = laspy.LasData(header)
    las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
    las.intensity = fields["intensity"]
    las.gps_time = np.arange(N_SEED, dtype=np.float64)
    if "red" in las.point_format.dimension_names:
        las.red, las.green, las.blue = (colours[:, k].astype(np.uint16) * 257 for k in range(3))
    las.write(str(path))


def _text_rows(*columns, fmt="%.6f", sep=" "):
    table = np.column_stack(columns)
    return "".join(sep.join(fmt % v for v in row) + "\n" for row in table)


def seed_files(directory) -> dict:
    """Write one valid 120-point file of every variant of :data:`VARIANTS`.

    Parameters
    ----------
    directory : str or os.PathLike
        An existing directory; the files are named ``seed-VARIANT.EXT``.

    Returns
    -------
    dict of str to pathlib.Path
        The file of each variant. PLY: binary little endian by
        :func:`heatcurv.io.write_points` (normals, colours, fields), ascii and
        binary big endian with a ``face`` element by plyfile; LAS 1.2 point
        format 3 and LAS 1.4 format 7 by laspy, LAS 1.4 format 6 (normals as
        extra bytes) by ``write_points``; LAZ 1.2 format 3 by laspy, LAZ 1.4
        format 7 by ``write_points``; XYZ, TXT, CSV and NPZ by
        ``write_points``; a CloudCompare-style CSV (``//X,Y,Z,R,G,B``), a PTS
        (count line, ``x y z intensity r g b``), an OBJ (``v`` with colours,
        ``vn``, ``f``) and a COFF with faces written by hand; an NPY (120, 6).
    """
    from heatcurv.io import write_points

    directory = Path(directory)
    points, normals, colours, fields = _seed_cloud()
    files = {name: directory / f"seed-{name}{variant.ext}" for name, variant in VARIANTS.items()}
    full = dict(normals=normals, colours=colours)
    write_points(files["ply-binary-le"], points, fields, **full)
    _write_plyfile(files["ply-ascii-faces"], points, normals, colours, True, "=")
    _write_plyfile(files["ply-binary-be-faces"], points, normals, colours, False, ">")
    _write_laspy(files["las-1.2-fmt3"], points, colours, fields, 3, "1.2")
    write_points(files["las-1.4-fmt6"], points, fields, normals=normals)
    _write_laspy(files["las-1.4-fmt7"], points, colours, fields, 7, "1.4")
    _write_laspy(files["laz-1.2-fmt3"], points, colours, fields, 3, "1.2")
    write_points(files["laz-1.4-fmt7"], points, fields, **full)
    for name in ("xyz", "txt", "csv", "npz"):
        write_points(files[name], points, fields, **full)
    files["csv-hand"].write_text("//X,Y,Z,R,G,B\n" + _text_rows(points, colours, fmt="%.6g", sep=","))
    files["pts"].write_text(f"{N_SEED}\n" + _text_rows(points, fields["intensity"], colours, fmt="%.6g"))
    vertices = "".join("v " + line for line in _text_rows(points, colours / 255.0).splitlines(True))
    vns = "".join("vn " + line for line in _text_rows(normals).splitlines(True))
    faces = "".join(f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}\n" for a, b, c in _faces())
    files["obj"].write_text("# heatcurv fuzz seed\n" + vertices + vns + faces)
    files["off"].write_text(f"COFF\n# heatcurv fuzz seed\n{N_SEED} {N_SEED - 2} 0\n"
                            + _text_rows(points, colours, np.full(N_SEED, 255), fmt="%.6g")
                            + "".join(f"3 {a} {b} {c}\n" for a, b, c in _faces()))
    np.save(files["npy"], np.column_stack([points, normals]))
    return files


# -------------------------------------------------------------------------------------------- mutators
def mutators_for(variant) -> list:
    """The mutators of :data:`MUTATORS` that apply to a variant (a name or a :class:`Variant`)."""
    variant = VARIANTS[variant] if isinstance(variant, str) else variant
    return [m for m in MUTATORS.values() if m.applies(variant.family, variant.textual)]


#: Mutators that change only how a file describes its data: a mutated file they leave readable must read as
#: its seed, every attribute the same (:func:`attribute_differences`); one that does not was misread.
EXACT_OR_REFUSED = frozenset({
    "las-point-count", "las-vlr-count", "las-point-offset", "las-record-length", "las-scale", "las-offset-bbox",
    "las-format", "las-vlr", "las-point-format", "las-misalign", "laz-chunk-table", "laz-vlr",
})


# ------------------------------------------------------------------------------------- what is run
def attribute_digests(cloud) -> dict:
    """A digest of every attribute of a :class:`~heatcurv.io.PointCloud`: its dtype, shape and bytes.

    Returns
    -------
    dict of str to str
        ``points``, ``normals``, ``colours`` (when present), ``faces`` (the
        ``meta["faces"]`` entry, when present) and ``field NAME`` for each
        field; equal digests mean bit-identical values.
    """
    import hashlib

    arrays = {"points": cloud.points, "normals": cloud.normals, "colours": cloud.colours}
    arrays.update({f"field {name}": values for name, values in cloud.fields.items()})
    digests = {}
    for name, values in arrays.items():
        if values is None:
            continue
        values = np.ascontiguousarray(values)
        digest = hashlib.sha1(values.view(np.uint8).reshape(-1) if values.dtype.kind != "O" else repr(values).encode())
        digests[name] = f"{values.dtype.str} {values.shape} {digest.hexdigest()}"
    if cloud.meta.get("faces") is not None:
        digests["faces"] = repr(cloud.meta["faces"])
    return digests


def attribute_differences(original: dict, accepted: dict) -> str:
    """How the attributes of an accepted file differ from its original's (:func:`attribute_digests`), or "".

    Returns
    -------
    str
        ``"attributes differ from the original: points, field 'x'; missing: normals; new: field 'y'"``
        (the parts that apply), or an empty string when every attribute is the same.
    """
    parts = []
    changed = [name for name in original if name in accepted and accepted[name] != original[name]]
    missing = [name for name in original if name not in accepted]
    new = [name for name in accepted if name not in original]
    if changed:
        parts.append(", ".join(changed))
    if missing:
        parts.append("missing: " + ", ".join(missing))
    if new:
        parts.append("new: " + ", ".join(new))
    return "attributes differ from the original: " + "; ".join(parts) if parts else ""


def read_summary(path) -> dict:
    """Read a file with :func:`heatcurv.io.read_points` (in the worker) and check the cloud's contract.

    Returns
    -------
    dict
        ``points`` (count), ``finite`` (all coordinates finite), ``faces``
        (``meta["faces"]`` or None), ``problems``: how the
        :class:`~heatcurv.io.PointCloud` breaks its documented shapes and
        types (an empty list when it keeps them), and ``attributes``
        (:func:`attribute_digests`).
    """
    from heatcurv.io import read_points

    cloud = read_points(path)
    points = cloud.points
    n = points.shape[0] if points.ndim == 2 else -1
    problems = []
    if points.dtype != np.float64 or points.ndim != 2 or points.shape[1] != 3:
        problems.append(f"points of shape {points.shape} and dtype {points.dtype}")
    if cloud.normals is not None and cloud.normals.shape != (n, 3):
        problems.append(f"normals of shape {cloud.normals.shape}")
    if cloud.colours is not None and (cloud.colours.shape != (n, 3) or cloud.colours.dtype != np.uint8):
        problems.append(f"colours of shape {cloud.colours.shape} and dtype {cloud.colours.dtype}")
    problems += [f"field {name!r} of length {len(v)}" for name, v in cloud.fields.items() if len(v) != n]
    finite = bool(np.isfinite(points).all()) if points.dtype.kind == "f" else True
    return {"points": n, "finite": finite, "faces": cloud.meta.get("faces"), "problems": problems,
            "attributes": attribute_digests(cloud)}


def warm_estimate() -> None:
    """Run :func:`heatcurv.estimate` once on a small sphere, so its numba kernels are compiled (or loaded)."""
    import heatcurv
    from heatcurv.surfaces import Sphere

    heatcurv.estimate(Sphere().sample(400, "fibonacci").points)


def estimate_summary(points, normals=None, **options) -> dict:
    """Run :func:`heatcurv.estimate` (in the worker) and return its per-point arrays and kernel.

    Returns
    -------
    dict
        ``normals mean gaussian k1 k2 area reliable outlier`` (arrays), ``k``
        (the chord fit's kernel in neighbours, ``info["scale"].k``, or None),
        ``n_distinct``, and from ``info["orientation"]`` the numbers of
        points oriented ``by_convention`` (nearly flat parts: not rotation
        invariant, by design) and ``ambiguous``.
    """
    import heatcurv

    res = heatcurv.estimate(points, normals, **options)
    out = {name: getattr(res, name) for name in ("normals", "mean", "gaussian", "k1", "k2", "area", "reliable",
                                                  "outlier")}
    scale, orientation = res.info.get("scale"), res.info.get("orientation")
    out["k"] = getattr(scale, "k", None)
    out["n_distinct"] = res.info.get("n_distinct")
    out["by_convention"] = getattr(orientation, "by_convention", 0)
    out["ambiguous"] = getattr(orientation, "ambiguous", 0)
    return out


# ------------------------------------------------------------------------------------ classification
#: What a wrapped third-party error looks like: an exception class name or an object repr anywhere, or a
#: generic "not a valid ... file" followed by nothing but a number, a quoted token or empty parentheses.
_OPAQUE_CODE = r"\(\s*(?:-?\d+|'[^'\s]*'|\"[^\"\s]*\"|)\s*\)"
_OPAQUE = re.compile(
    r"\(\s*[A-Za-z_][\w.]*(?:Error|Exception|Exit|Interrupt|Warning)\s*\)|<\w[^>]* at 0x|"
    r"Traceback \(most recent|<class '|"
    r"^(?:not an? |an? )?(?:valid |invalid |readable |corrupt |damaged |bad )?[\w/ .-]*?"
    r"(?:file|archive|data|header|error|stream)\s*" + _OPAQUE_CODE + r"\s*$", re.IGNORECASE)


def message_problem(message: str, path) -> str | None:
    """Why a HeatcurvError's message breaks the one-line promise, or None if it keeps it.

    It keeps it when it is one line, names ``path``, and says something after
    it in words: not a bare exception name (``(MemoryError)``), an object
    repr or a traceback, and not a generic ``not a valid LAS/LAZ file``
    followed by nothing but an opaque code (``(35)``, ``('x')``, ``()``);
    without control characters and in at most 400 characters. A number in
    parentheses that goes with words is fine (``an unknown compressor (99)``).
    """
    path = str(path)
    if "\n" in message or "\r" in message:
        return "spans several lines"
    if path not in message:
        return "does not name the file"
    problem = message.split(path, 1)[1].lstrip(": ")
    if not problem.strip():
        return "names no problem"
    if _OPAQUE.search(problem):
        return "wraps an opaque code or object instead of saying the problem"
    if any(ord(c) < 32 or 127 <= ord(c) < 160 for c in message):
        return "holds control characters"
    if len(problem) > 400:
        return f"is {len(problem)} characters long"
    return None


def classify(reply: Reply, path, size: int, *, memory_factor=MEMORY_FACTOR, memory_base=MEMORY_BASE) -> tuple:
    """The outcome of one read (see :data:`OUTCOMES`) and a one-line detail.

    Parameters
    ----------
    reply : Reply
        What the worker answered.
    path : str or os.PathLike
        The file read; a HeatcurvError must name it.
    size : int
        The file's size in bytes (the memory threshold scales with it).

    Returns
    -------
    (str, str)
    """
    if reply.kind in ("crash", "hang"):
        return reply.kind, reply.message
    threshold = memory_factor * size + memory_base
    if reply.memory_error:
        return "memory", f"MemoryError under the address-space limit: {reply.message.splitlines()[0][:300]}"
    if reply.peak > threshold:
        return "memory", f"peak memory grew by {reply.peak / 2**20:.0f} MiB for a {size}-byte file"
    if reply.kind == "value":
        return "ok", ""
    first = (reply.message.splitlines() or [""])[0][:300]
    if not any(t.endswith("HeatcurvError") for t in reply.types):
        return "exception", f"{reply.types[0] if reply.types else '?'}: {first}"
    problem = message_problem(reply.message, path)
    if problem:
        return "bad-message", f"the message {problem}: {reply.message[:300]!r}"
    return "error", reply.message


def announced_points(family: str, data: bytes) -> set | None:
    """The point counts a file's own header announces (the read count must be one of them), or None.

    PLY: ``element vertex``; OFF: the vertex count; PTS: the first line's
    counts (one line per scan, added up); NPY: the shape's first dimension; LAS/LAZ: the legacy count and,
    from LAS 1.4 on, the 64-bit count where it is not 0. None for formats
    without a count (XYZ, TXT, CSV, OBJ, NPZ) or a header that does not parse.
    """
    try:
        if family == "ply":
            found = re.search(rb"^element vertex (\d+)\s*$", data[: header_end(data)], re.M)
            return {int(found.group(1))} if found else None
        if family in ("las", "laz"):
            counts = {struct.unpack_from("<I", data, 107)[0]}
            if data[24:26] >= b"\x01\x04" and len(data) >= 255:
                counts.add(struct.unpack_from("<Q", data, 247)[0])
            return (counts - {0}) or {0}
        if family == "pts":  # one count line per scan: the counts add up
            counts = [ln.strip() for ln in data.split(b"\n") if re.fullmatch(rb"\s*[-+]?\d+\s*", ln)]
            return {sum(int(c) for c in counts)} if counts else None
        if family == "off":
            lines = [ln.split(b"#")[0].split() for ln in data.split(b"\n")[:4] if ln.split(b"#")[0].strip()]
            tokens = lines[1] if len(lines[0]) == 1 else lines[0][1:]  # "OFF" then counts, or "OFF n f e"
            return {int(tokens[0])}
        if family == "npy":
            return {int(npy_header(data)[0]["shape"][0])}
    except (ValueError, IndexError, KeyError, TypeError, SyntaxError, struct.error, MemoryError, RecursionError):
        return None
    return None


def _undetectable(variant: Variant, data: bytes, summary: dict, mutator: str) -> bool:
    """The one documented case an accepted file may differ from its seed: a point-wise LAZ read short.

    LAZ point formats 0-5 store no point count in a chunk: a header count lowered
    within the last chunk decodes the first points, exactly, and nothing can tell.
    """
    return (variant.family == "laz" and mutator == "las-point-count" and len(data) > 104
            and data[104] & 0x3F <= 5 and summary.get("points", N_SEED) < N_SEED)


def _contradiction(variant: Variant, data: bytes, summary: dict, mutator: str = "", original=None) -> str:
    problems = list(summary.get("problems", []))
    if mutator in EXACT_OR_REFUSED and original is not None and not _undetectable(variant, data, summary, mutator):
        differences = attribute_differences(original, summary.get("attributes", {}))
        if differences:
            problems.append(differences)
    counts = announced_points(variant.family, data)
    if counts is not None and summary["points"] not in counts:
        problems.append(f"the header announces {min(counts)} points, {summary['points']} were read")
    if variant.family in ("las", "laz") and len(data) >= 155:
        scales = struct.unpack_from("<3d", data, 131)
        bad = [s for s in scales if not np.isfinite(s) or s == 0]
        if bad:
            problems.append(f"accepted with a scale of {bad[0]!r}")
    return "; ".join(problems)


# ------------------------------------------------------------------------------------------ campaign
@dataclass
class CaseResult:
    """One mutated file and what reading it did."""

    variant: str
    mutator: str
    case_seed: int
    outcome: str
    detail: str
    size: int
    seconds: float
    peak: int
    contradiction: str = ""

    @property
    def reproduce(self) -> str:
        """The command that writes this case's file and reads it in-process, with the traceback."""
        return f"{REPLAY} {self.variant} {self.mutator} {self.case_seed}"

    def __str__(self) -> str:
        text = f"{self.variant} / {self.mutator}: {self.outcome}: {self.detail}"
        if self.contradiction:
            text += f" [contradiction: {self.contradiction}]"
        return f"{text}  (reproduce: {self.reproduce})"


@dataclass
class Campaign:
    """The results of :func:`run_campaign`: one :class:`CaseResult` per mutated file."""

    results: list = field(default_factory=list)
    seconds: float = 0.0
    restarts: int = 0

    def counts(self) -> dict:
        """``{variant: Counter(outcome -> count)}``, contradictions counted as ``"contradiction"``."""
        table = {}
        for r in self.results:
            row = table.setdefault(r.variant, Counter())
            row[r.outcome] += 1
            row["contradiction"] += bool(r.contradiction)
        return table

    def failures(self) -> list:
        """The cases whose outcome is one of :data:`FAILURES`."""
        return [r for r in self.results if r.outcome in FAILURES]

    def contradictions(self) -> list:
        """The accepted cases that contradict their own header."""
        return [r for r in self.results if r.contradiction]

    def rows(self) -> tuple:
        """``(header, rows)`` of the outcome table: variant x outcome counts, worst time and peak memory."""
        header = ["variant", *OUTCOMES, "contradiction", "worst s", "worst MiB"]
        rows = []
        for variant, counts in self.counts().items():
            mine = [r for r in self.results if r.variant == variant]
            rows.append([variant, *(str(counts[o]) for o in OUTCOMES + ("contradiction",)),
                         f"{max(r.seconds for r in mine):.2f}", f"{max(r.peak for r in mine) / 2**20:.0f}"])
        return header, rows


def _case_seed(seed: int, variant: str, index: int) -> int:
    return int(np.random.SeedSequence([seed, zlib.crc32(variant.encode()), index]).generate_state(1)[0])


def run_campaign(n_per_format: int = 60, seed: int = 0, *, variants=None, mutators=None, timeout: float = TIMEOUT,
                 memory_limit: int = MEMORY_LIMIT, directory=None, progress=None) -> Campaign:
    """Mutate every seed ``n_per_format`` times and read each file in a :class:`Worker`.

    Parameters
    ----------
    n_per_format : int
        Mutated files per variant; the variant's mutators take turns
        (round robin), so each runs about ``n / len(mutators_for(variant))`` times.
    seed : int
        The campaign's seed: the same seed gives the same files.
    variants, mutators : iterable of str, optional
        Restrict to these variants / mutator names (default: all).
    timeout : float
        Seconds per case.
    memory_limit : int
        The worker's ``RLIMIT_AS`` headroom, bytes.
    directory : str or os.PathLike, optional
        Where the seeds and the mutated files go (default: a temporary directory, removed).
    progress : callable, optional
        Called with each :class:`CaseResult`.

    Returns
    -------
    Campaign
    """
    start = time.monotonic()
    campaign = Campaign()
    with tempfile.TemporaryDirectory(prefix="heatcurv-fuzz-") as scratch, Worker(memory_limit) as worker:
        directory = Path(directory or scratch)
        seeds = seed_files(directory)
        for name in variants or VARIANTS:
            variant, data = VARIANTS[name], seeds[name].read_bytes()
            chosen = [m for m in mutators_for(name) if mutators is None or m.name in mutators]
            original = None
            if any(m.name in EXACT_OR_REFUSED for m in chosen):
                seed_reply = worker.call(read_summary, str(seeds[name]), timeout=timeout)
                original = seed_reply.value["attributes"] if seed_reply.kind == "value" else None
            for index in range(n_per_format if chosen else 0):
                mutator, case_seed = chosen[index % len(chosen)], _case_seed(seed, name, index)
                mutated = mutate(data, mutator.name, case_seed)
                path = directory / f"{name}-{index}-{mutator.name}{variant.ext}"
                path.write_bytes(mutated)
                reply = worker.call(read_summary, str(path), timeout=timeout)
                factor = COMPRESSED_MEMORY_FACTOR.get(variant.ext, MEMORY_FACTOR)
                outcome, detail = classify(reply, path, len(mutated), memory_factor=factor)
                contradiction = (_contradiction(variant, mutated, reply.value, mutator.name, original)
                                 if outcome == "ok" else "")
                result = CaseResult(name, mutator.name, case_seed, outcome, detail, len(mutated), reply.seconds,
                                    reply.peak, contradiction)
                campaign.results.append(result)
                path.unlink()
                if progress is not None:
                    progress(result)
        campaign.restarts = worker.restarts
    campaign.seconds = time.monotonic() - start
    return campaign


def _reproduce(argv=None) -> int:
    import argparse
    import traceback

    from heatcurv.io import read_points

    parser = argparse.ArgumentParser(prog=REPLAY,
                                     description="Write one fuzz case's file and read it in this process.")
    parser.add_argument("variant", choices=sorted(VARIANTS))
    parser.add_argument("mutator", choices=sorted(MUTATORS))
    parser.add_argument("seed", type=int, help="the case seed printed by the campaign")
    parser.add_argument("--keep", metavar="DIR", help="write the mutated file here (default: a temporary directory)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        directory = Path(args.keep or scratch)
        directory.mkdir(parents=True, exist_ok=True)
        data = seed_files(scratch)[args.variant].read_bytes()
        path = directory / f"{args.variant}-{args.mutator}-{args.seed}{VARIANTS[args.variant].ext}"
        path.write_bytes(mutate(data, args.mutator, args.seed))
        print(f"{path} ({path.stat().st_size} bytes)")
        try:
            cloud = read_points(path)
        except Exception:
            traceback.print_exc()
            return 1
        print(f"read {cloud.points.shape[0]} points")
    return 0


if __name__ == "__main__":
    sys.exit(_reproduce())
