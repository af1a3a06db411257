"""Normal orientation on closed objects with thin parts: CGAL's twelve animal and figure models.

The clouds are the used vertices of CGAL's closed models (fetched by
:func:`support.scans.fetch_cgal_meshes`: armadillo, bear, bull,
camel, cow, dino, diplodocus, elephant, elk, homer, lion, man; ``lion`` has
small holes), the truth is the mesh's outward area-weighted vertex normals
(:meth:`support.scans.Mesh.outward_vertex_normals`). Each model is
run in three variants:

``clean``   the vertices as they are;
``noisy``   Gaussian noise of 0.1 % of the bounding-box diagonal added to
            every coordinate (``numpy.random.default_rng(0)``);
``half``    a random half of the vertices (``default_rng(0).permutation``,
            the first ``n // 2``), to the same truth.

Columns

``points``               the cloud's size;
``thin %``               points on parts under 3 spacings thick: the
                         thickness of a vertex is the distance along its
                         inward normal to the first triangle of the mesh that
                         does not contain it (a ray cast against the mesh's
                         triangles near the vertex, numba), the spacing the
                         median distance from a vertex to its nearest other
                         vertex; a property of the mesh, the same in every
                         variant;
``wrong %``              normal . truth < 0 among all points;
``wrong on thick %``     the same among the points at least 3 spacings thick;
``wrong & reliable %``   (heatcurv, tiled) wrong and flagged reliable
                         (``res.reliable``), % of all points;
``inward & reliable %``  (heatcurv, tiled) of those, the normals within 60
                         degrees of the inward truth (``normal . truth <
                         -0.5``): the side turned over, not an axis more than
                         60 degrees off (a coarse feature's normal, whose
                         side is then hardly defined);
``flagged %``            (heatcurv, tiled) not reliable;
``s``                    seconds of the call alone (heatcurv's numba kernels
                         compiled by a warm-up beforehand).

A second table, **sides on resolved parts**, reads only the points a sample
at the mesh's spacing can decide: on parts at least 3 spacings thick *and*
with at least 3 spacings of open space along their outward normal before the
next part of the mesh (a hand against a hip, an arm against the torso, two
legs together put both surfaces in one ball as a thin part does), the share
whose normal is within 60 degrees of the inward truth: the side turned over,
not an axis off at a crease (``wrong %`` counts both).

Methods

``heatcurv``  ``heatcurv.estimate(points)``, the default options (normals
              oriented outward, :mod:`heatcurv.orient.orientation`); its rows are in
              input order, exact duplicate vertices share values.
``tiled``     ``heatcurv.compute_file`` of the same cloud (an NPY file) forced into
              at least 4 tiles (``tile_size = n // 4``, the serial scheduler):
              a tiled run's orientation (:mod:`heatcurv.tiles.orient`, then the
              winding number over every tile's sources, :mod:`heatcurv.tiles.winding`).
``open3d``    Open3D: ``estimate_normals(KDTreeSearchParamKNN(30))`` then
              ``orient_normals_consistent_tangent_plane(30)`` (the minimum
              spanning tree propagation of Hoppe et al.). Its global sign is
              arbitrary: its ``wrong %`` columns use the better of the two
              global signs (chosen on all points of the cloud). Needs
              ``pip install open3d`` (the ``peers`` extra); skipped with a note
              when missing.
``wnnc``      a winding-number orientation: the iteration of WNNC (Lin, Shi
              and Liu 2024), heatcurv's re-implementation
              (:mod:`heatcurv.orient.consistency`, run on every point by
              ``benchmarks/wnnc.py``; the authors' code needs a PyTorch
              extension), 40 iterations, the
              width preset of :data:`WNNC_PRESET`. Its normals are the
              winding field's gradient, outward by construction; it flags
              nothing.

Usage::

    python benchmarks/orientation.py                        # every model, variant and method
    python benchmarks/orientation.py --models camel,cow --variants clean --methods heatcurv
    python benchmarks/orientation.py --markdown --coarse-tori --plates --beside-sheet
    python benchmarks/orientation.py --markdown --methods wnnc --wnnc-presets   # WNNC's three presets

``--data DIR`` picks the cache directory of the models (default
:func:`support.scans.cgal_cache_dir`). A full run takes about 11
minutes on the 2-core machine (WNNC's N-body sums about 3 of them); the wall time is printed at the
end.
"""

from __future__ import annotations

import argparse
import datetime
import functools
import importlib.util
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numba
import numpy as np
import scipy
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import surfaces as hs

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # tests/support: the real scans
from machine import commit, cpu_model, memory_text  # noqa: E402  (benchmarks/machine.py)
from machine import table as text_table  # noqa: E402
from support.scans import CGAL_MESHES, fetch_cgal_meshes, read_mesh  # noqa: E402

MODELS = tuple(name.removesuffix(".off") for name in CGAL_MESHES)
VARIANTS = ("clean", "noisy", "half")
METHODS = ("heatcurv", "tiled", "open3d", "wnnc")
#: the methods that flag points (their "wrong & reliable" and "flagged" columns)
FLAGGING = ("heatcurv", "tiled")
#: the WNNC width preset of each variant (benchmarks/wnnc.py): the authors' presets measured on these
#: models, l0, l1 and l2, the best pooled share inside out chosen for each variant
WNNC_PRESET = {"clean": "l1", "noisy": "l1", "half": "l1"}
#: parts thinner than this many spacings are "thin"
THIN_SPACINGS = 3.0
#: noise of the noisy variant, a fraction of the bounding-box diagonal
NOISE = 1e-3
KNN = 30


# ---------------------------------------------------------------------------
# the models and their thickness
# ---------------------------------------------------------------------------


@numba.njit(parallel=True, cache=True)
def _first_hits(origins, directions, own, start, candidates, v0, e1, e2, faces, eps, cap):  # pragma: no cover
    """Distance along ``directions[i]`` from ``origins[i]`` to the nearest candidate triangle without vertex ``own[i]``.

    Möller-Trumbore ray-triangle tests against the triangles
    ``candidates[start[i]:start[i + 1]]``; hits at ``t <= eps`` are ignored;
    ``inf`` where nothing is hit before ``cap``.
    """
    n = origins.shape[0]
    out = np.full(n, np.inf)
    for i in numba.prange(n):
        best = cap
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        for k in range(start[i], start[i + 1]):
            f = candidates[k]
            if faces[f, 0] == own[i] or faces[f, 1] == own[i] or faces[f, 2] == own[i]:
                continue
            ax, ay, az = e1[f, 0], e1[f, 1], e1[f, 2]
            bx, by, bz = e2[f, 0], e2[f, 1], e2[f, 2]
            px, py, pz = dy * bz - dz * by, dz * bx - dx * bz, dx * by - dy * bx
            det = ax * px + ay * py + az * pz
            if det == 0.0:
                continue
            inv = 1.0 / det
            sx, sy, sz = origins[i, 0] - v0[f, 0], origins[i, 1] - v0[f, 1], origins[i, 2] - v0[f, 2]
            u = (sx * px + sy * py + sz * pz) * inv
            if u < 0.0 or u > 1.0:
                continue
            qx, qy, qz = sy * az - sz * ay, sz * ax - sx * az, sx * ay - sy * ax
            v = (dx * qx + dy * qy + dz * qz) * inv
            if v < 0.0 or u + v > 1.0:
                continue
            t = (bx * qx + by * qy + bz * qz) * inv
            if eps < t < best:
                best = t
        out[i] = best if best < cap else np.inf
    return out


def thickness(mesh, normals: np.ndarray, cap: float) -> np.ndarray:
    """Distance from each vertex along ``-normals`` to the mesh's other side, ``inf`` beyond ``cap``, shape (n,).

    Only the triangles whose centroid lies within ``cap`` plus the largest
    centroid-to-corner distance of the vertex can be hit before ``cap``;
    those are the candidates of each ray.
    """
    v, f = mesh.vertices, mesh.faces
    corners = v[f]
    centroid = corners.mean(axis=1)
    reach = float(np.linalg.norm(corners - centroid[:, None], axis=2).max())
    lists = cKDTree(centroid).query_ball_point(v, r=cap + reach, workers=-1)
    sizes = np.fromiter(map(len, lists), dtype=np.int64, count=len(lists))
    start = np.concatenate([[0], np.cumsum(sizes)])
    candidates = np.concatenate([np.asarray(c, dtype=np.int64) for c in lists])
    eps = 1e-9 * float(np.linalg.norm(np.ptp(v, axis=0)))
    return _first_hits(v, -normals, np.arange(len(v)), start, candidates, corners[:, 0],
                       corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0], f, eps, cap)


def load_model(directory: Path, name: str) -> dict:
    """The model's vertices, outward normals, spacing and thickness mask (the used vertices only)."""
    mesh = read_mesh(directory / f"{name}.off")
    normals = mesh.outward_vertex_normals()
    used = mesh.used
    spacing = float(np.median(cKDTree(mesh.vertices).query(mesh.vertices, k=2)[0][:, 1]))
    thick = np.isinf(thickness(mesh, normals, THIN_SPACINGS * spacing))
    # the gap outside: along the outward normal to the next part (an arm against the torso, two legs together)
    clear = np.isinf(thickness(mesh, -normals, THIN_SPACINGS * spacing))
    return {"name": name, "points": mesh.vertices[used], "truth": normals[used], "thick": thick[used],
            "resolved": (thick & clear)[used], "spacing": spacing,
            "diagonal": float(np.linalg.norm(np.ptp(mesh.vertices, axis=0))), "closed": mesh.closed, "mesh": mesh}


def mesh_winding(mesh, queries: np.ndarray, chunk: int = 64) -> np.ndarray:
    """The mesh's generalised winding number at ``queries`` (van Oosterom-Strackee solid angles), shape (q,)."""
    v, f = mesh.vertices, mesh.faces
    a0, b0, c0 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    out = np.zeros(len(queries))
    for lo in range(0, len(queries), chunk):
        q = queries[lo:lo + chunk, None]
        a, b, c = a0 - q, b0 - q, c0 - q
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc + np.einsum("pfi,pfi->pf", b, c) * la
               + np.einsum("pfi,pfi->pf", c, a) * lb)
        out[lo:lo + chunk] = (2.0 * np.arctan2(det, den)).sum(axis=1) / (4.0 * np.pi)
    return out


def inside_own_solid(model: dict, points: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Points whose outside, a third of a spacing along the mesh's outward normal, is inside the mesh's own solid.

    Where a mesh intersects itself (an arm through a torso) its vertices there lie inside another part:
    "outward" is not defined, and the truth of those points is doubtful.
    """
    return mesh_winding(model["mesh"], points + model["spacing"] / 3.0 * truth) > 0.5


def variant(model: dict, kind: str, seed: int = 0):
    """The cloud, its truth and thickness mask of one variant."""
    points, truth, thick = model["points"], model["truth"], model["thick"]
    rng = np.random.default_rng(seed)
    if kind == "noisy":
        return points + rng.normal(scale=NOISE * model["diagonal"], size=points.shape), truth, thick
    if kind == "half":
        keep = half_rows(len(points), rng)
        return points[keep], truth[keep], thick[keep]
    return points, truth, thick


def half_rows(n: int, rng) -> np.ndarray:
    """The sorted rows of the ``half`` variant, shape (n // 2,)."""
    return np.sort(rng.permutation(n)[: n // 2])


def variant_resolved(model: dict, kind: str, seed: int = 0) -> np.ndarray:
    """The ``resolved`` mask (parts and the gaps outside them at least 3 spacings) of one variant's points."""
    resolved = model["resolved"]
    return resolved[half_rows(len(resolved), np.random.default_rng(seed))] if kind == "half" else resolved


# ---------------------------------------------------------------------------
# the methods
# ---------------------------------------------------------------------------


def run_heatcurv(points: np.ndarray):
    tic = time.perf_counter()
    with warnings.catch_warnings():  # an undecided cloud warns; its report says so
        warnings.simplefilter("ignore", heatcurv.HeatcurvWarning)
        res = heatcurv.estimate(points)
    seconds = time.perf_counter() - tic
    DECISIONS.append(res.info["orientation"])
    return res.normals, res.reliable, seconds


#: the in-memory runs' orientation reports, in run order (the decision tables)
DECISIONS: list = []
#: the tiled runs' orientation reports (dicts), in run order
TILED_REPORTS: list = []


def decision(report) -> str:
    """What the winding number made of a cloud: closed, undecided or open."""
    return "closed" if report.closed else "undecided" if report.undecided else "open"


def median_roundness(points: np.ndarray) -> float:
    """The median ball's PCA roundness (``lambda_0 / lambda_1`` of the 60 nearest, tapered, as the estimator's)."""
    from heatcurv.geometry.neighbourhood import knn_neighbourhood
    from heatcurv.orient.normals import pca_normals

    _, _, roundness = pca_normals(points, knn_neighbourhood(points, 60), taper=True, roundness=True)
    return float(np.nanmedian(roundness))


def decision_row(name: str, points: np.ndarray, report, wrong: float, silent: float) -> list[str]:
    return [name, f"{100 * report.agreement:.1f}", f"{100 * report.outside_share:.1f}", decision(report),
            f"{median_roundness(points):.2f}", f"{wrong:.2f}", f"{silent:.2f}"]


DECISION_HEAD = ["cloud", "levels agree %", "outside near 0 %", "decision", "roundness", "wrong %",
                 "wrong & reliable %"]


def coarse_tori() -> list[list[str]]:
    """Tori with a thin tube (radius 0.08-0.15 of the ring's), a few hundred random points: closed, but coarse."""
    cells = []
    for r, n in ((0.08, 800), (0.1, 600), (0.1, 800), (0.1, 1000), (0.12, 700), (0.15, 500), (0.15, 600), (0.2, 800),
                 (0.2, 1500)):
        for seed in (0, 1, 2):
            sample = hs.Torus(r, 1.0).sample(n, "random", seed=seed)
            normals, reliable, _ = run_heatcurv(sample.points)
            wrong = np.einsum("ij,ij->i", normals, sample.normals) < 0
            cells.append(decision_row(f"torus r {r}, {n} points, seed {seed}", sample.points, DECISIONS[-1],
                                      100 * wrong.mean(),
                                      100 * (wrong & reliable).mean()))
    return cells


PLATE_HEAD = ["cloud", "thickness / h", "orientation", "layered %", "split %", "inward %", "inward & reliable %",
              "second sheet %", "reliable %", "tiled inward & reliable %"]


def plates() -> list[list[str]]:
    """Flattened ellipsoids 1 x 1 x c lying flat and turned 30/50/20 degrees: in memory and in 4 tiles."""
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_euler("xyz", (30.0, 50.0, 20.0), degrees=True).as_matrix()
    cells = []
    for c in (0.01, 0.02, 0.03, 0.04, 0.06, 0.08, 0.15):
        sample = hs.Ellipsoid(1.0, 1.0, c).sample(20000, "random", seed=0)
        spacing = None
        for pose, matrix in (("flat", np.eye(3)), ("turned", turn)):
            points, truth = sample.points @ matrix.T, sample.normals @ matrix.T
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", heatcurv.HeatcurvWarning)
                res = heatcurv.estimate(points)
            inward = np.einsum("ij,ij->i", res.normals, truth) < 0
            report = res.info["orientation"]
            spacing = float(np.median(res.spacing)) if spacing is None else spacing
            tiled_normals, tiled_reliable, _ = run_tiled(points)
            tiled_inward = np.einsum("ij,ij->i", tiled_normals, truth) < 0
            cells.append([f"c {c}, {pose}", f"{2 * c / spacing:.1f}", report.mode,
                          f"{100 * report.policy.layered:.1f}" if report.policy is not None else "-",
                          f"{100 * report.policy.split:.1f}" if report.policy is not None else "-",
                          f"{100 * inward.mean():.2f}", f"{100 * (inward & res.reliable).mean():.2f}",
                          f"{100 * res.info['second_sheet'] / len(points):.1f}", f"{100 * res.reliable.mean():.1f}",
                          f"{100 * (tiled_inward & tiled_reliable).mean():.2f}"])
    return cells


SHEET_HEAD = ["model", "sheet points", "decision", "open components", "model wrong on thick %",
              "model wrong & reliable %", "model flagged %", "sheet on one side %", "sheet reliable %",
              "tiled open components", "tiled normals equal %", "tiled reliable equal %"]


def beside_sheet(model: dict, multiple: float, seed: int = 1) -> np.ndarray:
    """An open sheet of ``multiple`` x the model's points beside it (half a diagonal away), shape (k, 3).

    Uniform random points over a square at about the model's spacing, bent into a shallow bowl
    (``z = 0.1 r^2 / side``, ``r`` from the square's centre): a scan's background, apart from the object.
    """
    points, spacing, diagonal = model["points"], model["spacing"], model["diagonal"]
    k = int(multiple * len(points))
    side = np.sqrt(k) * spacing * 1.1
    xy = np.random.default_rng(seed).uniform(0.0, side, (k, 2))
    z = 0.1 * ((xy - side / 2) ** 2).sum(axis=1) / side
    low, high = points.min(axis=0), points.max(axis=0)
    return np.column_stack([xy[:, 0] + high[0] + 0.5 * diagonal, xy[:, 1] + low[1], z + low[2]])


def sheets_beside(models: list[dict]) -> list[list[str]]:
    """Each model with an open sheet of 0, 0.5, 1 and 3 x its points beside it: in memory and in 4 tiles."""
    cells = []
    for model in models:
        n = len(model["points"])
        for multiple in (0.0, 0.5, 1.0, 3.0):
            points = np.vstack([model["points"], beside_sheet(model, multiple)])
            normals, reliable, _ = run_heatcurv(points)
            report = DECISIONS.pop()
            wrong = np.einsum("ij,ij->i", normals[:n], model["truth"]) < 0
            sheet_up = normals[n:, 2] > 0
            cells_row = [model["name"], f"{len(points) - n}",
                         decision(report) if report.mode == "outward" else report.mode,
                         f"{getattr(report, 'open_components', 0)}",
                         f"{100 * wrong[model['thick']].mean():.2f}", f"{100 * (wrong & reliable[:n]).mean():.2f}",
                         f"{100 * (~reliable[:n]).mean():.1f}",
                         f"{100 * max(sheet_up.mean(), 1 - sheet_up.mean()):.1f}" if len(points) > n else "-",
                         f"{100 * reliable[n:].mean():.1f}" if len(points) > n else "-"]
            tiled_normals, tiled_reliable, _ = run_tiled(points)
            cells_row += [f"{TILED_REPORTS[-1].get('open_components', 0)}",
                          f"{100 * np.mean(np.einsum('ij,ij->i', tiled_normals, normals) > 0.999):.2f}",
                          f"{100 * np.mean(tiled_reliable == reliable):.2f}"]
            cells.append(cells_row)
    return cells


def run_tiled(points: np.ndarray):
    import tempfile

    from heatcurv.io import read_points

    with tempfile.TemporaryDirectory() as work:
        src, dst = Path(work) / "cloud.npy", Path(work) / "out.ply"
        np.save(src, points)
        tic = time.perf_counter()
        report = heatcurv.compute_file(src, dst, tile_size=max(len(points) // 4, 500), scheduler="serial",
                                       dtype="float64", progress=False, fields=("nx", "ny", "nz", "reliable"))
        seconds = time.perf_counter() - tic
        TILED_REPORTS.append(report.orientation or {})
        out = read_points(dst)
    return out.normals, out.fields["reliable"].astype(bool), seconds


def run_open3d(points: np.ndarray):
    import open3d as o3d

    tic = time.perf_counter()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(KNN))
    cloud.orient_normals_consistent_tangent_plane(KNN)
    normals = np.asarray(cloud.normals).copy()
    return normals, None, time.perf_counter() - tic


def run_wnnc(points: np.ndarray, kind: str):
    from wnnc import wnnc_normals  # benchmarks/wnnc.py

    tic = time.perf_counter()
    normals = wnnc_normals(points, WNNC_PRESET[kind])
    return normals, None, time.perf_counter() - tic


def wnnc_presets(models: list[dict], kinds) -> list[list[str]]:
    """Every variant under each of WNNC's presets: the pooled shares (the choice of :data:`WNNC_PRESET`)."""
    from wnnc import PRESETS, wnnc_normals

    cells = []
    for kind in kinds:
        for preset in PRESETS:
            counts, seconds = np.zeros(6), 0.0
            for model in models:
                points, truth, thick = variant(model, kind)
                resolved = variant_resolved(model, kind)
                tic = time.perf_counter()
                dot = np.einsum("ij,ij->i", wnnc_normals(points, preset), truth)
                seconds += time.perf_counter() - tic
                counts += [len(dot), np.sum(dot < 0), thick.sum(), np.sum(dot[thick] < 0), resolved.sum(),
                           np.sum(dot[resolved] < -0.5)]
            cells.append([kind, preset, f"{100 * counts[1] / counts[0]:.2f}", f"{100 * counts[3] / counts[2]:.2f}",
                          f"{100 * counts[5] / counts[4]:.2f}", f"{seconds:.0f}"])
    return cells


def warm_up() -> None:
    """Compile heatcurv's numba kernels (clean and noisy clouds) before any clock starts."""
    torus = hs.Torus().sample(3000, "random", seed=1).points
    for points in (torus, torus + np.random.default_rng(2).normal(scale=0.02, size=torus.shape)):
        heatcurv.estimate(points)


def measure(normals: np.ndarray, reliable, truth: np.ndarray, thick: np.ndarray, either_sign: bool,
            resolved: np.ndarray | None = None) -> dict:
    """The wrong-side shares (%) of one method's normals; a normal without value (NaN) counts as wrong.

    ``inward_resolved``: the share of the ``resolved`` points whose normal is within 60 degrees of the
    inward truth (the side turned over, not an axis off at a crease).
    """
    dot = np.einsum("ij,ij->i", normals, truth)
    wrong = ~(dot >= 0)  # NaN: wrong
    flipped = False
    if either_sign and np.count_nonzero(~(dot <= 0)) < np.count_nonzero(wrong):
        wrong, flipped = ~(dot <= 0), True
    out = {"wrong": 100.0 * wrong.mean(), "wrong_thick": 100.0 * wrong[thick].mean() if thick.any() else np.nan,
           "flipped": flipped, "nan": int(np.count_nonzero(~np.isfinite(dot)))}
    inward = (dot > 0.5) if flipped else (dot < -0.5)
    if resolved is not None:
        out["inward_resolved"] = 100.0 * np.mean(inward[resolved])
    if reliable is not None:
        out["wrong_reliable"] = 100.0 * np.mean(wrong & reliable)
        out["inward_reliable"] = 100.0 * np.mean(inward & reliable)
        out["flagged"] = 100.0 * np.mean(~reliable)
    return out


# ---------------------------------------------------------------------------
# tables
# ---------------------------------------------------------------------------


def header_row(methods) -> list[str]:
    head = ["model", "points", "thin %"]
    for m in methods:
        head += [f"{m} wrong %", f"{m} wrong on thick %"]
        if m in FLAGGING:
            head += [f"{m} wrong & reliable %", f"{m} inward & reliable %", f"{m} flagged %"]
        head += [f"{m} s"]
    return head


def row(name: str, n: int, thin: float, results: dict, methods) -> list[str]:
    cells = [name, str(n), f"{thin:.2f}"]
    for m in methods:
        r = results.get(m)
        if r is None:
            cells += ["-"] * (6 if m in FLAGGING else 3)
            continue
        cells += [f"{r['wrong']:.2f}", f"{r['wrong_thick']:.2f}"]
        if m in FLAGGING:
            cells += [f"{r['wrong_reliable']:.2f}", f"{r['inward_reliable']:.2f}", f"{r['flagged']:.1f}"]
        cells += [f"{r['seconds']:.2f}"]
    return cells


def pooled(rows: list[dict], methods) -> dict:
    """Point-weighted means of every share over the rows (the 'all' line)."""
    n = np.array([r["n"] for r in rows], dtype=float)
    out = {}
    for m in methods:
        if not all(m in r["results"] for r in rows):
            continue
        res = [r["results"][m] for r in rows]
        nthick = np.array([r["nthick"] for r in rows], dtype=float)
        entry = {"wrong": float(np.sum(n * [x["wrong"] for x in res]) / n.sum()),
                 "wrong_thick": float(np.nansum(nthick * [x["wrong_thick"] for x in res]) / nthick.sum()),
                 "seconds": float(sum(x["seconds"] for x in res))}
        if m in FLAGGING:
            entry["wrong_reliable"] = float(np.sum(n * [x["wrong_reliable"] for x in res]) / n.sum())
            entry["inward_reliable"] = float(np.sum(n * [x["inward_reliable"] for x in res]) / n.sum())
            entry["flagged"] = float(np.sum(n * [x["flagged"] for x in res]) / n.sum())
        out[m] = entry
    return out


def resolved_table(models: list[dict], by_kind: dict, methods) -> list[list[str]]:
    """One row per model and the pooled one: each variant's and method's ``inward_resolved``."""
    cells = []
    for i, model in enumerate(models + [None]):
        name = "all" if model is None else model["name"]
        share = 100.0 * np.mean(np.concatenate([m["resolved"] for m in models]) if model is None else model["resolved"])
        cells.append([name, f"{share:.1f}"])
        for rows in by_kind.values():
            for m in methods:
                picked = rows if model is None else [rows[i]]
                if not all(m in r["results"] for r in picked):
                    cells[-1].append("-")
                    continue
                weight = np.array([r["nresolved"] for r in picked], dtype=float)
                value = np.sum(weight * [r["results"][m]["inward_resolved"] for r in picked]) / weight.sum()
                cells[-1].append(f"{value:.2f}")
    return cells


def machine_lines() -> list[str]:
    lines = [
        f"date (UTC)   {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}",
        f"machine      {cpu_model()}, {os.cpu_count()} cores{memory_text()}; {platform.system()} {platform.release()}",
        f"python       {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"numba {numba.__version__}",
        f"heatcurv     {heatcurv.__version__} (commit {commit()})",
    ]
    if open3d_problem() is None:
        import open3d

        lines.append(f"open3d       {open3d.__version__}")
    return lines


def open3d_problem() -> str | None:
    """None if Open3D imports, else why not (not installed, or a system library missing)."""
    if importlib.util.find_spec("open3d") is None:
        return "open3d is not installed (pip install open3d)"
    try:
        import open3d  # noqa: F401
    except ImportError as exc:  # e.g. libusb-1.0.so.0 missing
        return f"open3d does not import: {exc}"
    return None


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)

    def names(allowed):
        def parse(text):
            chosen = [t.strip() for t in text.split(",") if t.strip()]
            bad = sorted(set(chosen) - set(allowed))
            if bad or not chosen:
                raise argparse.ArgumentTypeError(f"choose from {', '.join(allowed)} (got {text!r})")
            return chosen
        return parse

    parser.add_argument("--models", type=names(MODELS), default=list(MODELS), help="comma-separated model names")
    parser.add_argument("--variants", type=names(VARIANTS), default=list(VARIANTS), help="clean,noisy,half")
    parser.add_argument("--methods", type=names(METHODS), default=list(METHODS), help="heatcurv,tiled,open3d,wnnc")
    parser.add_argument("--data", default=None, help="cache directory of the models (default: cgal_cache_dir())")
    parser.add_argument("--markdown", action="store_true", help="print the tables as Markdown")
    parser.add_argument("--coarse-tori", action="store_true",
                        help="also run tori with a tube a few spacings across (the decision table)")
    parser.add_argument("--plates", action="store_true",
                        help="also run thin closed plates lying flat and turned (auto's choice, second sheets)")
    parser.add_argument("--wnnc-presets", action="store_true",
                        help="also a table of WNNC's three width presets, pooled over the models (about 10 minutes)")
    parser.add_argument("--beside-sheet", action="store_true",
                        help="also run each model with an open sheet beside it (each object judged on its own)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    wall = time.perf_counter()

    def log(msg):
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    methods = list(args.methods)
    notes = []
    if "open3d" in methods and open3d_problem() is not None:
        methods.remove("open3d")
        notes.append(f"{open3d_problem()}: its columns are left out")
    print("Normal orientation on CGAL's closed models")
    print("\n".join(machine_lines()))
    print(f"load         1-minute load average {os.getloadavg()[0]:.1f} (other work on the machine slows the times)")
    print()
    directory = fetch_cgal_meshes(args.data)
    if "heatcurv" in methods or "tiled" in methods:
        warm_up()
    models = []
    for name in args.models:
        tic = time.perf_counter()
        models.append(load_model(directory, name))
        m = models[-1]
        log(f"{name}: {len(m['points'])} points, spacing {m['spacing']:.4g}, thin {100 * (~m['thick']).mean():.2f} %"
            f" ({time.perf_counter() - tic:.1f} s)")
    runners = {"heatcurv": run_heatcurv, "tiled": run_tiled, "open3d": run_open3d}
    if "wnnc" in methods:
        from wnnc import wnnc_normals

        wnnc_normals(hs.Torus().sample(500, "random", seed=1).points, iterations=2)  # compile before any clock
    decisions = []
    resolved_rows = {}
    for kind in args.variants:
        runners["wnnc"] = functools.partial(run_wnnc, kind=kind)  # its width preset is chosen per variant
        rows = []
        own_solid = []
        for model in models:
            points, truth, thick = variant(model, kind)
            results = {}
            for method in methods:
                normals, reliable, seconds = runners[method](points)
                r = measure(normals, reliable, truth, thick, either_sign=(method == "open3d"),
                            resolved=variant_resolved(model, kind))
                r["seconds"] = seconds
                results[method] = r
                if method == "heatcurv":
                    silent = np.flatnonzero(~(np.einsum("ij,ij->i", normals, truth) >= 0) & reliable)
                    # judged at the mesh's own vertices (a noisy point's noise is not the mesh's doing)
                    vertex = cKDTree(model["points"]).query(points[silent])[1] if silent.size else silent
                    inside = int(inside_own_solid(model, model["points"][vertex], model["truth"][vertex]).sum())
                    if inside:
                        own_solid.append(f"{model['name']} {inside} of {silent.size}")
                    decisions.append(decision_row(f"{model['name']} {kind}", points, DECISIONS[-1], r["wrong"],
                                                  r["wrong_reliable"]))
                if r["nan"]:
                    notes.append(f"{kind} {model['name']}: {method} left {r['nan']} normals without value (wrong)")
                log(f"{kind} {model['name']}: {method} wrong {r['wrong']:.2f} %, {seconds:.2f} s")
            rows.append({"name": model["name"], "n": len(points), "thin": 100.0 * (~thick).mean(),
                         "nthick": int(thick.sum()), "nresolved": int(variant_resolved(model, kind).sum()),
                         "results": results})
        cells = [row(r["name"] + ("" if models[i]["closed"] else " (holes)"), r["n"], r["thin"], r["results"], methods)
                 for i, r in enumerate(rows)]
        n_all = sum(r["n"] for r in rows)
        thin_all = sum(r["thin"] * r["n"] for r in rows) / n_all
        cells.append(row("all", n_all, thin_all, pooled(rows, methods), methods))
        resolved_rows[kind] = rows
        title = f"{kind}: % of points whose normal points into the object"
        if "open3d" in methods:
            title += " (open3d: the better of its two global signs)"
        print(text_table(title, header_row(methods), cells, args.markdown))
        if own_solid:
            notes.append(f"{kind}: heatcurv's inside out and reliable points that lie inside the mesh's own solid (the "
                         f"mesh intersects itself there; outward is not defined): {', '.join(own_solid)}")
    print(text_table("sides on resolved parts: % of the points of parts at least 3 spacings thick, with a gap of at "
                     "least 3 spacings outside them, whose normal is within 60 degrees of the inward truth",
                     ["model", "resolved %"] + [f"{kind} {m}" for kind in resolved_rows for m in methods],
                     resolved_table(models, resolved_rows, methods), args.markdown))
    if args.plates:
        print(text_table("thin plates lying flat: ellipsoids 1 x 1 x c, 20 000 random points (truth: the ellipsoid's "
                         "outward normals; h: heatcurv's median spacing, res.spacing; layered: the share auto's sample "
                         "found over or under another sheet; split: the share of auto's sample whose balls' residuals "
                         "split in two layers)",
                         PLATE_HEAD, plates(), args.markdown))
    if decisions:
        print(text_table("heatcurv: closed, undecided or open (the winding number's two shares; closed from 30 % "
                         "agreeing, undecided from 10 % (from 0 where the sources' median roundness is at least "
                         "0.2) with the outside near 0 on at least 50 %)",
                         DECISION_HEAD, decisions, args.markdown))
    if args.beside_sheet:
        print(text_table("each model (clean) with an open sheet beside it: a shallow bowl of 0.5-3 x its points, half "
                         "a diagonal away (sheet on one side: the share of its normals on their majority side; tiled: "
                         "4 tiles or more, against the in-memory run)", SHEET_HEAD, sheets_beside(models),
                         args.markdown))
    if args.wnnc_presets:
        print(text_table("WNNC's width presets (benchmarks/wnnc.py), pooled over the models: % inside out, on thick "
                         "parts, and turned over on resolved parts", ["variant", "preset", "wrong %",
                                                                      "wrong on thick %", "inward on resolved %", "s"],
                         wnnc_presets(models, args.variants), args.markdown))
    if args.coarse_tori:
        print(text_table("coarse thin tori (closed; truth: the torus's outward normals; roundness: the median "
                         "ball's lambda_0 / lambda_1, too coarse from 0.65 on half of the balls)", DECISION_HEAD,
                         coarse_tori(), args.markdown))
    for note in notes:
        print(f"note: {note}")
    print(f"wall time {time.perf_counter() - wall:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
