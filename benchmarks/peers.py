"""Time and peak memory of peer tools on one point cloud, one subprocess per tool.

Each peer runs in a fresh Python process (``python benchmarks/peers.py
--child NAME FILE``, started with :data:`sys.executable`), so its wall time
and its peak resident memory are its own and no peer warms a cache for the
next one.  The child loads the points from an ``.npy`` file (float64, shape
``(n, 3)``), imports the peer's package, then times the computation alone
with :func:`time.perf_counter` and prints its measurements as JSON lines on
stdout.  The last line is the result; :func:`run_peer` parses it.

Peers (:data:`PEERS`, in this order)

``knn40``
    SciPy ``cKDTree`` build plus a ``k = 40`` self-query with
    ``workers=-1``: the reference the other times are compared to.
``open3d-normals``
    Open3D ``PointCloud.estimate_normals(KDTreeSearchParamKNN(40))``: PCA
    normals only, not oriented, no curvature.  The timed part includes
    building the ``open3d.geometry.PointCloud`` from the array.
``pymeshlab-apss``
    PyMeshLab: point-cloud normals (``compute_normal_for_point_clouds``,
    ``k = 40``), then APSS curvature per vertex
    (``compute_curvature_and_color_apss_per_vertex``, default scale and
    projection settings) twice, ``curvaturetype="Mean"`` and ``"Gauss"``.
    Single-threaded.  The timed part is all three filters plus building the
    ``MeshSet``; the stages are reported separately.
``robust-laplacian``
    ``robust_laplacian.point_cloud_laplacian(points)`` (package defaults,
    ``n_neighbors=30``): the sparse Laplacian ``L`` and mass matrix ``M``.
``heatcurv-quadric``
    :func:`support.baseline.quadric_curvature` with ``k = 40``: oriented
    normals, principal curvatures and directions from k-NN quadric fits.
``cloudcompare-curv``
    The CloudCompare command line (Debian's ``cloudcompare`` package,
    ``QT_QPA_PLATFORM=offscreen CloudCompare -SILENT -O cloud.ply -CURV MEAN
    r -SAVE_CLOUDS``): its quadric mean curvature in a ball of radius ``r``
    chosen to hold about ``k = 40`` points (the median 40th-neighbour
    distance of 2000 points, computed before the clock starts), as a user
    runs it: the timed part is the whole command, reading the binary PLY,
    the curvature and writing the result. Its peak memory is the command's
    own (``RUSAGE_CHILDREN``).

Every computation is one cold call in a fresh process (no warm-up run), as a
user's first call would be.

Peak memory
    ``peak_rss_gb`` is the peak resident set size of the child process,
    read from ``VmHWM`` in ``/proc/self/status`` (Linux), in GB (1e9
    bytes).  It includes the interpreter, the imported libraries and the
    loaded array.  ``rss_before_gb`` is the same figure just before the
    computation starts (after loading and importing), so
    ``peak_rss_gb - rss_before_gb`` approximates what the computation
    itself added.  ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` is used
    only where ``/proc`` is missing: on Linux a process started from a
    parent inherits the parent's peak RSS in ``ru_maxrss`` across
    ``fork``/``exec`` (checked on this machine: a parent that had touched
    2 GB starts a child whose ``ru_maxrss`` reads 1.93 GB while its
    ``VmHWM`` reads 9 MB), which would make every peer look at least as big
    as the benchmark process that launched it.

Run as a script, ``python benchmarks/peers.py [--n 100000] [--timeout 600]``
samples a random torus (:class:`heatcurv.surfaces.Torus`), saves it to a
temporary ``.npy`` file, runs every peer and prints a plain-text table.
"""

from __future__ import annotations

import argparse
import atexit
import importlib.util
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

__all__ = [
    "PEERS",
    "PACKAGES",
    "NOTES",
    "installed",
    "run_peer",
    "run_peers",
    "save_points",
    "format_table",
]

#: Peer names, in the order they are run and printed.
PEERS = ("knn40", "open3d-normals", "pymeshlab-apss", "robust-laplacian", "heatcurv-quadric", "cloudcompare-curv")

#: Importable module that each peer needs (checked by :func:`installed`).
PACKAGES = {
    "knn40": "scipy",
    "open3d-normals": "open3d",
    "pymeshlab-apss": "pymeshlab",
    "robust-laplacian": "robust_laplacian",
    "heatcurv-quadric": "heatcurv",
    "cloudcompare-curv": "exe:CloudCompare",
}

#: What each peer computes (the ``note`` of its row).
NOTES = {
    "knn40": "cKDTree build + k=40 self-query, workers=-1",
    "open3d-normals": "normals only (unoriented PCA), k=40; incl. array->PointCloud",
    "pymeshlab-apss": "point-cloud normals k=40 + APSS Mean + APSS Gauss (default APSS settings)",
    "robust-laplacian": "L and M, n_neighbors=30 (package default)",
    "heatcurv-quadric": "k=40 quadric fit: oriented normals, k1, k2, d1, d2, H, K",
    "cloudcompare-curv": "command line: read PLY + CURV MEAN (ball of about 40 points) + write; mean curvature only",
}

#: Default per-peer time limit, seconds.
DEFAULT_TIMEOUT = 600.0

#: Neighbours used by the k-NN peers.
K = 40

_GB = 1e9


# --------------------------------------------------------------------------
# Parent side
# --------------------------------------------------------------------------


def installed(name: str) -> bool:
    """Whether the package a peer needs can be found.

    Parameters
    ----------
    name : str
        A peer name from :data:`PEERS`.

    Returns
    -------
    bool
        True if :func:`importlib.util.find_spec` finds the peer's module.
        This does not import it: a package that is present but fails to
        import (e.g. a missing shared library) is installed, and its row
        then says ``failed: ...``.

    Raises
    ------
    KeyError
        If ``name`` is not a peer.
    """
    module = PACKAGES[name]
    if module.startswith("exe:"):
        return shutil.which(module[4:]) is not None
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def save_points(points, path: str) -> str:
    """Save points as the float64, C-contiguous ``(n, 3)`` ``.npy`` file the children read.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Point coordinates.
    path : str
        Destination file name (should end in ``.npy``).

    Returns
    -------
    str
        ``path``.
    """
    array = np.ascontiguousarray(points, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {array.shape}")
    np.save(path, array)
    return path


def _row(name: str, status: str, seconds=None, peak_rss_gb=None, note=None, **extra) -> dict:
    row = {
        "name": name,
        "status": status,
        "seconds": seconds,
        "peak_rss_gb": peak_rss_gb,
        "note": NOTES.get(name, "") if note is None else note,
        "cpu_seconds": None,
        "rss_before_gb": None,
        "stages": {},
    }
    row.update(extra)
    return row


def _json_lines(text) -> list[dict]:
    """The JSON objects among the lines of a child's stdout (other lines ignored)."""
    if text is None:
        return []
    if isinstance(text, bytes):
        text = text.decode("utf-8", errors="replace")
    objects = []
    for line in text.splitlines():
        line = line.strip()
        if not (line.startswith("{") and line.endswith("}")):
            continue
        try:
            value = json.loads(line)
        except ValueError:
            continue
        if isinstance(value, dict):
            objects.append(value)
    return objects


def _last_line(text) -> str:
    if text is None:
        return ""
    if isinstance(text, bytes):
        text = text.decode("utf-8", errors="replace")
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else ""


def _exit_reason(returncode: int) -> str:
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exit code {returncode}"


def _format_seconds(seconds: float) -> str:
    return f"{seconds:g}"


def run_peer(name: str, points_file: str, timeout: float = DEFAULT_TIMEOUT) -> dict:
    """Run one peer on a point file in its own subprocess and measure it.

    Parameters
    ----------
    name : str
        A peer name from :data:`PEERS`.
    points_file : str
        ``.npy`` file with a float64 array of shape ``(n, 3)``
        (see :func:`save_points`).
    timeout : float, optional
        Seconds after which the child is killed (default 600).  The limit
        covers the whole child: start-up, loading, import and computation.

    Returns
    -------
    dict
        ``name`` : str
            The peer.
        ``status`` : str
            ``"ok"``, ``"not installed"``, ``"timeout after N s"`` or
            ``"failed: <one-line reason>"``.
        ``seconds`` : float or None
            Wall time of the computation only (no file loading, no package
            import), measured in the child with :func:`time.perf_counter`.
        ``peak_rss_gb`` : float or None
            Peak RSS of the child in GB (1e9 bytes); includes the
            interpreter, the imported libraries and the loaded array.
        ``note`` : str
            What exactly was computed.
        ``cpu_seconds`` : float or None
            User + system CPU time of the child during the computation (all
            threads): ``cpu_seconds / seconds`` is about the number of cores
            kept busy.
        ``rss_before_gb`` : float or None
            Peak RSS of the child just before the computation.
        ``stages`` : dict
            Seconds per stage for multi-step peers (``knn40``,
            ``open3d-normals``, ``pymeshlab-apss``); on a timeout, the
            stages that finished.

        ``seconds``, ``peak_rss_gb``, ``cpu_seconds`` and ``rss_before_gb``
        are None unless the status is ``"ok"``.

    Raises
    ------
    KeyError
        If ``name`` is not a peer.
    """
    if name not in PEERS:
        raise KeyError(f"unknown peer {name!r}; peers are {', '.join(PEERS)}")
    if not installed(name):
        return _row(name, "not installed")
    command = [sys.executable, os.path.abspath(__file__), "--child", name, os.fspath(points_file)]
    try:
        completed = subprocess.run(
            command, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
        )
    except subprocess.TimeoutExpired as expired:
        stages = {}
        for obj in _json_lines(expired.stdout):
            if "stage" in obj:
                stages[obj["stage"]] = obj["seconds"]
        note = NOTES[name]
        if stages:
            done = ", ".join(f"{stage} {sec:.2f} s" for stage, sec in stages.items())
            note += f"; finished before the timeout: {done}"
        return _row(name, f"timeout after {_format_seconds(timeout)} s", note=note, stages=stages)

    results = [obj for obj in _json_lines(completed.stdout) if "status" in obj]
    if results:
        result = results[-1]
        row = _row(name, result.get("status", "failed: no status"))
        for key in row:
            if key in result:
                row[key] = result[key]
        if completed.returncode != 0 and row["status"] == "ok":
            row["status"] = f"failed: {_exit_reason(completed.returncode)} after reporting"
        return row
    reason = _exit_reason(completed.returncode)
    detail = _last_line(completed.stderr) or _last_line(completed.stdout)
    message = f"{reason}: {detail}" if detail else f"{reason}, no output"
    return _row(name, f"failed: {message}")


def run_peers(points_file: str, timeout: float = DEFAULT_TIMEOUT, names=PEERS, progress=None) -> list[dict]:
    """Run several peers one after the other (see :func:`run_peer`).

    Parameters
    ----------
    points_file : str
        ``.npy`` file with a float64 array of shape ``(n, 3)``.
    timeout : float, optional
        Per-peer time limit, seconds.
    names : sequence of str, optional
        Peers to run, in order (default: all of :data:`PEERS`).
    progress : callable, optional
        Called with each row as soon as it is measured.

    Returns
    -------
    list of dict
        One row per peer, in the order of ``names``.
    """
    rows = []
    for name in names:
        row = run_peer(name, points_file, timeout=timeout)
        rows.append(row)
        if progress is not None:
            progress(row)
    return rows


def format_table(rows, reference: str = "knn40") -> str:
    """Plain-text table of peer rows.

    Parameters
    ----------
    rows : sequence of dict
        Rows from :func:`run_peer`.
    reference : str, optional
        Peer whose time is the unit of the ``x knn40`` column (default
        ``"knn40"``); the column is blank where either time is missing.

    Returns
    -------
    str
        Columns: name, status, seconds, ``x knn40`` (time / reference
        time), ``cpu/wall`` (cores kept busy), peak RSS GB, note.
    """
    reference_seconds = None
    for row in rows:
        if row["name"] == reference and row.get("seconds"):
            reference_seconds = row["seconds"]
    header = ("name", "status", "seconds", f"x {reference}", "cpu/wall", "peak RSS GB", "note")
    table = [header]
    for row in rows:
        seconds = row.get("seconds")
        cpu = row.get("cpu_seconds")
        peak = row.get("peak_rss_gb")
        table.append(
            (
                row["name"],
                row["status"],
                "" if seconds is None else f"{seconds:.3f}",
                "" if seconds is None or not reference_seconds else f"{seconds / reference_seconds:.1f}",
                "" if seconds is None or cpu is None or seconds <= 0 else f"{cpu / seconds:.2f}",
                "" if peak is None else f"{peak:.3f}",
                row.get("note") or "",
            )
        )
    widths = [max(len(line[i]) for line in table) for i in range(len(header) - 1)]
    numeric = {2, 3, 4, 5}
    out = []
    for index, line in enumerate(table):
        cells = [
            cell.rjust(widths[i]) if i in numeric and index > 0 else cell.ljust(widths[i])
            for i, cell in enumerate(line[:-1])
        ]
        out.append("  ".join(cells + [line[-1]]).rstrip())
        if index == 0:
            out.append("  ".join("-" * w for w in widths + [len(header[-1])]))
    return "\n".join(out)


# --------------------------------------------------------------------------
# Child side
# --------------------------------------------------------------------------


def peak_rss_bytes() -> int:
    """Peak RSS of this process, bytes: ``VmHWM`` (Linux), else ``ru_maxrss``.

    See the module docstring for why ``ru_maxrss`` is not used on Linux.
    """
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024  # kB
    except OSError:
        pass
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return maxrss if sys.platform == "darwin" else maxrss * 1024  # bytes on macOS, kB elsewhere


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _emit(obj: dict) -> None:
    print(json.dumps(obj), flush=True)


class _Stages:
    """Per-stage wall times of one computation, each printed as soon as it ends.

    A stage line (``{"stage": ..., "seconds": ...}``) reaches the parent even
    if the child is later killed by the timeout.
    """

    def __init__(self):
        self.seconds = {}
        self._start = None

    def start(self):
        self._start = time.perf_counter()

    def stop(self, stage: str):
        elapsed = time.perf_counter() - self._start
        self.seconds[stage] = elapsed
        _emit({"stage": stage, "seconds": elapsed})
        self._start = time.perf_counter()


def _prepare_knn40():
    from scipy.spatial import cKDTree

    def compute(points, stages):
        stages.start()
        tree = cKDTree(points)
        stages.stop("build")
        distances, indices = tree.query(points, k=K, workers=-1)
        stages.stop("query")
        return distances, indices

    return compute


def _prepare_open3d_normals():
    import open3d as o3d

    def compute(points, stages):
        stages.start()
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        stages.stop("to PointCloud")
        cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(K))
        stages.stop("estimate_normals")
        normals = np.asarray(cloud.normals)
        if normals.shape != points.shape:
            raise RuntimeError(f"open3d returned normals of shape {normals.shape}")
        return normals

    return compute


def _prepare_pymeshlab_apss():
    import pymeshlab

    def compute(points, stages):
        stages.start()
        mesh_set = pymeshlab.MeshSet()
        mesh_set.add_mesh(pymeshlab.Mesh(vertex_matrix=points))
        stages.stop("to MeshSet")
        mesh_set.compute_normal_for_point_clouds(k=K)
        stages.stop("normals (compute_normal_for_point_clouds)")
        mesh_set.compute_curvature_and_color_apss_per_vertex(curvaturetype="Mean")
        mean = mesh_set.current_mesh().vertex_scalar_array().copy()
        stages.stop("APSS Mean")
        mesh_set.compute_curvature_and_color_apss_per_vertex(curvaturetype="Gauss")
        gaussian = mesh_set.current_mesh().vertex_scalar_array().copy()
        stages.stop("APSS Gauss")
        if mean.shape[0] != points.shape[0]:
            raise RuntimeError(f"pymeshlab returned {mean.shape[0]} values for {points.shape[0]} points")
        return mean, gaussian

    return compute


def _prepare_robust_laplacian():
    import robust_laplacian

    def compute(points, stages):
        return robust_laplacian.point_cloud_laplacian(points)

    return compute


def _prepare_heatcurv_quadric():
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
    from support.baseline import quadric_curvature  # tests/support: test-only helpers

    def compute(points, stages):
        return quadric_curvature(points, k=K)

    return compute


def _write_binary_ply(points: np.ndarray, path: str) -> None:
    """``points`` as a binary little-endian PLY of double x, y, z (what CloudCompare reads)."""
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {points.shape[0]}\n"
              "property double x\nproperty double y\nproperty double z\nend_header\n")
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(np.ascontiguousarray(points, dtype="<f8").tobytes())


def _prepare_cloudcompare_curv():
    from scipy.spatial import cKDTree

    executable = shutil.which("CloudCompare")
    if executable is None:
        raise RuntimeError("CloudCompare is not on the PATH")
    directory = tempfile.mkdtemp(prefix="heatcurv-cc-")
    atexit.register(shutil.rmtree, directory, True)

    def setup(points):
        """Write the PLY and choose the radius, before the clock starts."""
        source = os.path.join(directory, "cloud.ply")
        _write_binary_ply(points, source)
        sample = points[np.random.default_rng(0).choice(points.shape[0], min(2000, points.shape[0]), replace=False)]
        radius = float(np.median(cKDTree(points).query(sample, K)[0][:, -1]))
        return source, radius

    def compute(prepared, stages):
        source, radius = prepared
        command = [executable, "-SILENT", "-NO_TIMESTAMP", "-C_EXPORT_FMT", "PLY", "-O", source,
                   "-CURV", "MEAN", f"{radius:.9g}", "-SAVE_CLOUDS", "FILE", os.path.join(directory, "out.ply")]
        env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
        done = subprocess.run(command, capture_output=True, text=True, env=env, stdin=subprocess.DEVNULL)
        if done.returncode != 0 or not os.path.exists(os.path.join(directory, "out.ply")):
            raise RuntimeError(f"CloudCompare {_exit_reason(done.returncode)}: {_last_line(done.stdout)}")
        return done

    compute.setup = setup
    compute.own_memory = True  # the command's peak RSS, not this process's
    return compute


#: Child-side setup per peer: imports the package (not timed) and returns
#: ``compute(points, stages)`` (timed).
_PREPARE = {
    "knn40": _prepare_knn40,
    "open3d-normals": _prepare_open3d_normals,
    "pymeshlab-apss": _prepare_pymeshlab_apss,
    "robust-laplacian": _prepare_robust_laplacian,
    "heatcurv-quadric": _prepare_heatcurv_quadric,
    "cloudcompare-curv": _prepare_cloudcompare_curv,
}


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    text = f"{type(error).__name__}: {text}" if text else type(error).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _child_main(name: str, points_file: str) -> int:
    """Measure one peer in this process and print the JSON result line.

    Returns the process exit code (0 whenever a result line was printed).
    """
    if name not in PEERS:
        _emit(_row(name, f"failed: unknown peer {name!r}", note=""))
        return 0
    if not installed(name):
        _emit(_row(name, "not installed"))
        return 0
    try:
        points = np.ascontiguousarray(np.load(points_file), dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {points.shape}")
    except Exception as error:  # noqa: BLE001 - reported in the row
        _emit(_row(name, f"failed: loading {points_file}: {_one_line(error)}"))
        return 0
    try:
        compute = _PREPARE[name]()
    except Exception as error:  # noqa: BLE001 - e.g. a missing shared library
        _emit(_row(name, f"failed: import: {_one_line(error)}"))
        return 0

    try:
        prepared = compute.setup(points) if hasattr(compute, "setup") else points
    except Exception as error:  # noqa: BLE001 - reported in the row
        _emit(_row(name, f"failed: setup: {_one_line(error)}"))
        return 0
    stages = _Stages()
    rss_before = peak_rss_bytes()
    cpu_start = _cpu_seconds()
    start = time.perf_counter()
    try:
        result = compute(prepared, stages)
    except Exception as error:  # noqa: BLE001 - reported in the row
        _emit(_row(name, f"failed: {_one_line(error)}", stages=stages.seconds))
        return 0
    seconds = time.perf_counter() - start
    cpu_seconds = _cpu_seconds() - cpu_start
    del result
    peak = peak_rss_bytes()
    if getattr(compute, "own_memory", False):  # a command's own peak and CPU time, not this process's
        children = resource.getrusage(resource.RUSAGE_CHILDREN)
        peak = children.ru_maxrss * (1 if sys.platform == "darwin" else 1024)
        cpu_seconds = children.ru_utime + children.ru_stime
        rss_before = 0

    note = NOTES[name]
    if stages.seconds:
        note += " [" + " + ".join(f"{stage} {sec:.2f} s" for stage, sec in stages.seconds.items()) + "]"
    _emit(
        _row(
            name,
            "ok",
            seconds=seconds,
            peak_rss_gb=peak / _GB,
            note=note,
            cpu_seconds=cpu_seconds,
            rss_before_gb=rss_before / _GB,
            stages=stages.seconds,
        )
    )
    return 0


# --------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------


def _torus_points(n: int) -> np.ndarray:
    from heatcurv.surfaces import Torus

    return Torus().sample(n, "random", seed=0).points


def main(argv=None) -> int:
    """Command-line entry: ``--child NAME FILE`` (internal) or the torus benchmark.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit code.
    """
    parser = argparse.ArgumentParser(
        description="Time and peak RSS of peer tools on a random torus, one subprocess per tool."
    )
    parser.add_argument("--n", type=int, default=100_000, help="number of points (default 100000)")
    parser.add_argument(
        "--timeout",
        type=float,
        default=DEFAULT_TIMEOUT,
        help=f"per-peer time limit in seconds (default {DEFAULT_TIMEOUT:g})",
    )
    parser.add_argument(
        "--peers", nargs="+", choices=PEERS, default=list(PEERS), help="peers to run (default: all)"
    )
    parser.add_argument(
        "--child", nargs=2, metavar=("NAME", "FILE"), help=argparse.SUPPRESS
    )
    args = parser.parse_args(argv)
    if args.child:
        return _child_main(*args.child)

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from machine import commit  # benchmarks/machine.py

    with tempfile.TemporaryDirectory(prefix="heatcurv-peers-") as directory:
        points_file = save_points(_torus_points(args.n), os.path.join(directory, "torus.npy"))
        print(
            f"random torus, n = {args.n}, timeout {args.timeout:g} s per peer, "
            f"{os.cpu_count()} CPUs, Python {sys.version.split()[0]}, heatcurv at commit {commit()}",
            flush=True,
        )
        rows = run_peers(
            points_file,
            timeout=args.timeout,
            names=args.peers,
            progress=lambda row: print(f"  {row['name']}: {row['status']}", file=sys.stderr, flush=True),
        )
    print(format_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
