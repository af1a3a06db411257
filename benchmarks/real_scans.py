"""heatcurv on real scans: measured checks that need no exact curvature, and pictures.

The scans

``bunny``        pymeshlab's ``bunny.obj``: a closed range scan of the Stanford bunny, 28 088 vertices;
``face``         pymeshlab's ``rangemaps/face000.ply``: one range map of a face (85 849 vertices,
                 stray points and holes) with its camera; run twice, with the default
                 orientation (``face``: up, a surface over the horizontal plane) and towards
                 the camera (``face_camera``,
                 ``viewpoint=range_camera(path)``);
``bone`` ``cow`` ``airplane``  pymeshlab's closed low-poly models (``bone.ply``, ``cow.obj``,
                 ``airplane.obj``); the cloud is their used vertices (those of a triangle);
``bunny1839``    the scan shipped with heatcurv (``heatcurv.data``, 1839 points, no mesh):
                 ``bunny.obj`` is registered onto it (similarity ICP) and read at the
                 nearest vertex;
``lidar``        ``heatcurv.surfaces.lidar_tile(20000, seed=0)`` with ``orient="up"``: a
                 simulated aerial LiDAR tile with exact normals per class;
``cad``          ``heatcurv.surfaces.cad_part(20000)``: a simulated closed CAD part with exact
                 normals, mean curvature, area and sharp edges;
CGAL's models    the twelve closed models of ``benchmarks/orientation.py`` (clean variant,
                 heatcurv alone): how many points come out inside out (``--no-closed`` skips them).

pymeshlab is GPL-3: its sample meshes are fetched at run time by
:func:`support.scans.fetch_pymeshlab_samples` (pinned wheel, SHA-256
checked, cached; ``$HEATCURV_TEST_DATA`` or ``--data`` picks the directory),
never shipped.

Every scan runs ``heatcurv.estimate`` (timed; numba compiled beforehand by a
warm-up), ``heatcurv.sharp_features`` on the result, and the estimate of a
random half of the points (``np.random.default_rng(seed).random(n) < 0.5``,
``--seed``), and is measured against what is known without an exact curvature:

* meshes: their area-weighted vertex normals (% of the non-outlier points whose
  normal is on the same side; wrong-side points, how many of them are flagged
  reliable and how many are "thin", i.e. their ball of the median fit radius
  reaches the other side of the closed mesh; median angle between the normal
  *lines* on reliable points), their area (also split into thin and other
  points, and for the open range map into the mesh's interior, its boundary
  and the points in no triangle), and their cotangent mean curvature
  (``H = -(Delta x . n) / 2``, as in ``tests/real/test_real_estimates.py``) off
  the mesh's boundary: the medians on reliable points, and the % with the same
  sign where the mesh's ``|H|`` is above its median and in its top 10 % (the
  estimate's sign aligned with the mesh's normals by one global flip);
* the scenes: their exact normals per class, the sign of the mean curvature on
  their convex and concave regions (also beyond one ball radius from an edge),
  the CAD part's exact area, and the recall of ``sharp_features`` on the points
  within 0.5 (m, mm) of a sharp edge (``scene.sharp``);
* every scan: outliers, ambiguous (unorientable) points, reliable %, and the
  orientation and total area of the random half against the whole.

Usage::

    python benchmarks/real_scans.py                            # tables to stdout
    python benchmarks/real_scans.py --out docs/real_scans.md   # + the page and docs/real_*.png
    python benchmarks/real_scans.py --only face --only cad --no-pictures

A full run takes one to two minutes on a 2-core machine (the face's two runs and
their halves are half of it); the wall time is printed at the end.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy
import scipy.sparse as sp
from scipy.spatial import cKDTree

import heatcurv
from heatcurv import surfaces as hs

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # tests/support: the real scans
from machine import commit, cpu_model, memory_text  # noqa: E402  (benchmarks/machine.py)
from machine import table as text_table  # noqa: E402

CASES = ("bunny", "face", "face_camera", "bone", "cow", "airplane", "bunny1839", "lidar", "cad")
#: picture size of a figure of two views (pixels)
PICTURE = (1600, 800)


# ---------------------------------------------------------------------------
# the scans and what is known about them
# ---------------------------------------------------------------------------


@dataclass
class Reference:
    """What a mesh says about the cloud's surface, per point.

    Attributes
    ----------
    source : str
        ``"mesh"`` (the points are the mesh's vertices) or ``"registered mesh"``.
    normals : ndarray, shape (n, 3)
        Area-weighted vertex normals; zero rows where the mesh has none (unused vertices).
    mean : ndarray, shape (n,)
        Cotangent mean curvature; NaN off the mesh and on its boundary.
    area : float
        The mesh's area; NaN where it does not measure the same surface.
    vertex_areas : ndarray, shape (n,), or None
        The mesh's barycentric vertex areas.
    piece : ndarray of int, shape (n,), or None
        The mesh component of each point; ``largest`` the largest one.
    closed : tuple (vertices, normals) or None
        The closed mesh's vertices and normals, for the thin-part test.
    residual : tuple of float or None
        Registration residual (median, 99th percentile), the cloud's units.
    boundary : ndarray of bool, shape (n,), or None
        Points on the open mesh's boundary (None: closed or not a vertex mesh).
    """

    source: str
    normals: np.ndarray
    mean: np.ndarray
    area: float = float("nan")
    vertex_areas: np.ndarray | None = None
    piece: np.ndarray | None = None
    largest: int = -1
    closed: tuple | None = None
    residual: tuple | None = None
    boundary: np.ndarray | None = None


@dataclass
class Case:
    """A cloud to estimate, with what is known about it."""

    key: str
    title: str
    what: str
    points: np.ndarray
    options: dict = field(default_factory=dict)
    ref: Reference | None = None
    scene: object = None  # heatcurv.surfaces.Scene
    camera: np.ndarray | None = None
    regions: dict = field(default_factory=dict)  # name -> mask, reported in the text
    unit: str = "length"
    n_vertices: int = 0  # the mesh's vertex count (the low-poly models)


def mesh_reference(mesh, index=None) -> Reference:
    """The mesh's normals, cotangent mean curvature, areas and pieces at its vertices ``index``."""
    index = np.arange(len(mesh)) if index is None else index
    used = mesh.used
    boundary = boundary_vertices(mesh)
    normals = mesh.vertex_normals()
    h = cotangent_mean_curvature(mesh)
    h[~used | boundary | ~np.isfinite(h)] = np.nan
    piece = mesh.components()
    labels, counts = np.unique(piece[used], return_counts=True)
    closed = None if boundary.any() else (mesh.vertices[used], normals[used])
    return Reference("mesh", normals[index], h[index], mesh.area, mesh.vertex_areas()[index], piece[index],
                     int(labels[np.argmax(counts)]), closed, boundary=boundary[index] if boundary.any() else None)


def similarity(src: np.ndarray, dst: np.ndarray):
    """Least-squares ``scale, rotation, shift`` with ``dst ~ scale * rotation @ src + shift`` (Umeyama)."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    u, s, vt = np.linalg.svd(b.T @ a / len(src))
    d = np.ones(3)
    d[2] = np.sign(np.linalg.det(u @ vt))
    rotation = u @ np.diag(d) @ vt
    scale = float(np.sum(s * d) / np.mean(np.sum(a * a, axis=1)))
    return scale, rotation, mu_d - scale * rotation @ mu_s


def registered_reference(mesh, points, iterations: int = 30) -> Reference:
    """The mesh moved onto the cloud (similarity ICP from the bounding boxes), read at each point's nearest vertex.

    Both are taken to share the axes' directions (y up); the scale and the
    position come from the bounding boxes, then ``iterations`` rounds of
    closest-vertex matching and :func:`similarity` refine them.
    """
    v = mesh.vertices
    box = 0.5 * (v.min(axis=0) + v.max(axis=0)), 0.5 * (points.min(axis=0) + points.max(axis=0))
    scale0 = float(np.mean(np.ptp(points, axis=0)) / np.mean(np.ptp(v, axis=0)))
    moved = (v - box[0]) * scale0 + box[1]
    for _ in range(iterations):
        _, nearest = cKDTree(moved).query(points)
        s, r, t = similarity(moved[nearest], points)
        moved = s * moved @ r.T + t
    scale, rotation, _ = similarity(v, moved)
    dist, nearest = cKDTree(moved).query(points)
    normals = mesh.vertex_normals() @ rotation.T
    h = cotangent_mean_curvature(mesh) / scale
    return Reference("registered mesh", normals[nearest], h[nearest],
                     closed=(moved[mesh.used], normals[mesh.used]),
                     residual=(float(np.median(dist)), float(np.percentile(dist, 99))))


def load_cases(names, data_dir) -> list[Case]:
    from heatcurv.data import bunny_path
    from heatcurv.io import read_points
    from support.scans import fetch_pymeshlab_samples, range_camera, read_mesh

    samples = None
    if set(names) - {"lidar", "cad"}:
        samples = fetch_pymeshlab_samples(data_dir)
    cases = []
    for name in names:
        if name == "bunny":
            mesh = read_mesh(samples / "bunny.obj")
            cases.append(Case(name, "bunny.obj", "closed range scan of the Stanford bunny", mesh.vertices,
                              ref=mesh_reference(mesh)))
        elif name in ("face", "face_camera"):
            path = samples / "rangemaps" / "face000.ply"
            mesh = read_mesh(path)
            camera = range_camera(path)
            ref = mesh_reference(mesh)
            if name == "face":
                cases.append(Case(name, "face000.ply", "one range map of a face, with stray points and holes",
                                  mesh.vertices, ref=ref, camera=camera, unit="mm"))
            else:
                cases.append(Case(name, "face000.ply + camera", "the same range map, normals towards its camera",
                                  mesh.vertices, {"viewpoint": camera}, ref=ref, camera=camera, unit="mm"))
        elif name in ("bone", "cow", "airplane"):
            file = {"bone": "bone.ply", "cow": "cow.obj", "airplane": "airplane.obj"}[name]
            mesh = read_mesh(samples / file)
            index = np.flatnonzero(mesh.used)
            cases.append(Case(name, file, f"closed low-poly model of a{'n' if name == 'airplane' else ''} {name}",
                              mesh.vertices[index], ref=mesh_reference(mesh, index), n_vertices=len(mesh)))
        elif name == "bunny1839":
            points = np.asarray(read_points(bunny_path()).points, dtype=np.float64)
            ref = registered_reference(read_mesh(samples / "bunny.obj"), points)
            cases.append(Case(name, "bunny_scan_1839.ply", "decimated Stanford bunny scan shipped with heatcurv",
                              points, ref=ref, regions={"ears (y > 6.5)": points[:, 1] > 6.5}))
        elif name == "lidar":
            scene = hs.lidar_tile(20000, seed=0)
            cases.append(Case(name, "lidar_tile(20000)", "simulated aerial LiDAR tile, 60 m x 60 m",
                              scene.points, {"orient": "up"}, scene=scene, unit="m"))
        elif name == "cad":
            scene = hs.cad_part(20000)
            cases.append(Case(name, "cad_part(20000)", "simulated closed CAD part: block, boss and hole",
                              scene.points, scene=scene, unit="mm"))
    return cases


# ---------------------------------------------------------------------------
# reference values of a mesh
# ---------------------------------------------------------------------------


def cotangent_mean_curvature(mesh):
    """The mesh's discrete mean curvature ``H = -(Delta x . n) / 2`` (cotangent Laplacian), shape (n,).

    As ``tests/real/test_real_estimates.py::cotangent_mean_curvature``; degenerate
    triangles get weight 0 and unused vertices NaN.
    """
    v, f = mesh.vertices, mesh.faces
    rows, cols, weights = [], [], []
    for k in range(3):
        i, j, o = f[:, k], f[:, (k + 1) % 3], f[:, (k + 2) % 3]
        a, b = v[i] - v[o], v[j] - v[o]
        with np.errstate(divide="ignore", invalid="ignore"):
            cot = np.einsum("ij,ij->i", a, b) / np.linalg.norm(np.cross(a, b), axis=1)
        cot = np.where(np.isfinite(cot), cot, 0.0)
        rows += [i, j]
        cols += [j, i]
        weights += [cot / 2, cot / 2]
    n = len(v)
    w = sp.csr_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    with np.errstate(divide="ignore", invalid="ignore"):
        laplacian = (w @ v - np.asarray(w.sum(axis=1)) * v) / mesh.vertex_areas()[:, None]
    return -np.einsum("ij,ij->i", laplacian, mesh.vertex_normals()) / 2


def boundary_vertices(mesh) -> np.ndarray:
    """Mask of the vertices on an edge used by one face only (the mesh's holes and rims)."""
    f = mesh.faces
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    mask = np.zeros(len(mesh), dtype=bool)
    mask[uniq[count == 1].ravel()] = True
    return mask


def thin_mask(points, normals, vertices, vertex_normals, radius: float, chunk: int = 4000) -> np.ndarray:
    """Points whose ball of ``radius`` reaches the other side of a closed mesh.

    The other side: a vertex within ``radius`` whose normal is more than 120
    degrees from the point's reference normal (``normals``), as across a thin
    leg, ear or plate.
    """
    tree = cKDTree(vertices)
    k = int(min(len(vertices), max(16, np.max(tree.query_ball_point(points, radius, return_length=True)))))
    out = np.zeros(len(points), dtype=bool)
    for lo in range(0, len(points), chunk):
        dist, idx = tree.query(points[lo:lo + chunk], k, distance_upper_bound=radius)
        dist, idx = dist.reshape(len(dist), -1), idx.reshape(len(idx), -1)
        inside = np.isfinite(dist)
        dots = np.einsum("ik,ijk->ij", normals[lo:lo + chunk], vertex_normals[np.where(inside, idx, 0)])
        out[lo:lo + chunk] = np.any(inside & (dots < -0.5), axis=1)
    return out


# ---------------------------------------------------------------------------
# running and measuring
# ---------------------------------------------------------------------------


def line_angle(a, b) -> np.ndarray:
    """Angle between the lines of unit vectors, degrees (0..90), shape (n,)."""
    return np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", a, b)), 0.0, 1.0)))


def pct(mask) -> float:
    mask = np.asarray(mask)
    return 100.0 * float(mask.mean()) if mask.size else float("nan")


def median(x) -> float:
    x = np.asarray(x)
    return float(np.median(x)) if x.size else float("nan")


def timed_estimate(points, options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tic = time.perf_counter()
        res = heatcurv.estimate(points, **options)
        seconds = time.perf_counter() - tic
    return res, seconds, [f"{w.category.__name__}: {w.message}" for w in caught]


def warm_up() -> None:
    """Compile numba's kernels (clean and noisy kernels, every orientation) before any clock starts."""
    torus = hs.Torus().sample(3000, "random", seed=1).points
    noisy = torus + np.random.default_rng(2).normal(scale=0.02, size=torus.shape)
    for points, options in ((torus, {}), (noisy, {}), (noisy, {"orient": "up"}), (torus, {"viewpoint": [0, 0, 9]})):
        heatcurv.sharp_features(heatcurv.estimate(points, **options))


def measure(case: Case, seed: int, log) -> dict:
    """Estimate the case's cloud and its random half, and measure the checks."""
    n = len(case.points)
    res, seconds, warned = timed_estimate(case.points, case.options)
    log(f"  estimate {seconds:.2f} s")
    feats = heatcurv.sharp_features(res)
    orientation, scale = res.info["orientation"], res.info.get("scale")
    m = {
        "n": n, "seconds": seconds, "warnings": warned, "res": res, "features": feats,
        "orient_mode": orientation.mode, "components": orientation.components, "ambiguous": orientation.ambiguous,
        "outliers": int(res.outlier.sum()), "reliable": pct(res.reliable), "n_features": int(feats.mask.sum()),
        "kernel": getattr(scale, "fit", "-"), "radius": float(getattr(scale, "median_radius", np.nan)),
        "area_total": float(res.area.sum()), "area_reliable": float(res.area[res.reliable].sum()),
        "spacing": float(np.median(cKDTree(case.points).query(case.points, 2)[0][:, 1])),
    }
    half = np.flatnonzero(np.random.default_rng(seed).random(n) < 0.5)
    part, half_seconds, half_warned = timed_estimate(case.points[half], case.options)
    log(f"  half     {half_seconds:.2f} s")
    keep = ~res.outlier[half] & ~part.outlier
    m["half_seconds"] = half_seconds
    m["half_n"] = int(half.size)
    m["warnings"] = warned + [f"(random half) {w}" for w in half_warned]
    same = np.einsum("ij,ij->i", res.normals[half], part.normals) > 0
    m["half_orient"] = pct(same[keep])
    if case.scene is not None:
        surface = np.isfinite(case.scene.normals[half]).all(axis=1)
        m["half_orient_surface"] = pct(same[keep & surface])
        m["half_orient_volume"] = pct(same[keep & ~surface]) if (keep & ~surface).any() else float("nan")
    m["half_area"] = 100.0 * (part.area.sum() / res.area.sum() - 1.0)
    half_scale = part.info.get("scale")
    m["half_kernel"] = getattr(half_scale, "fit", "-")
    m["half_radius"] = float(getattr(half_scale, "median_radius", np.nan))
    if case.ref is not None:
        measure_reference(case, res, m)
        if case.ref.closed is not None and np.isfinite(m["half_radius"]):
            m["half_thin"] = pct(thin_mask(case.points[half], case.ref.normals[half], *case.ref.closed,
                                           m["half_radius"]))
    if case.scene is not None:
        measure_scene(case, res, feats, m)
    if case.camera is not None:
        m["facing_camera"] = pct(np.einsum("ij,ij->i", res.normals, case.camera - case.points) > 0)
    return m


def measure_reference(case: Case, res, m: dict) -> None:
    ref = case.ref
    has = np.linalg.norm(ref.normals, axis=1) > 0
    ok = has & ~res.outlier
    dots = np.einsum("ij,ij->i", res.normals, ref.normals)
    wrong = ok & (dots <= 0)
    angles = line_angle(res.normals, ref.normals)
    m["ref_normals"] = ref.source
    m["orient"] = pct(dots[ok] > 0)
    m["n_oriented"] = int(ok.sum())
    m["wrong"] = int(wrong.sum())
    m["wrong_reliable"] = int((wrong & res.reliable).sum())
    m["angle"] = median(angles[ok & res.reliable])
    m["angle95"] = float(np.percentile(angles[ok & res.reliable], 95))
    if ref.piece is not None:
        m["wrong_small_pieces"] = int((wrong & (ref.piece != ref.largest)).sum())
    if ref.residual is not None:
        m["residual"] = ref.residual
    if ref.closed is not None and np.isfinite(m["radius"]):
        thin = thin_mask(case.points, ref.normals, *ref.closed, m["radius"])
        m["thin"] = pct(thin[ok])
        m["wrong_thin"] = pct(thin[wrong]) if wrong.any() else float("nan")
        m["reliable_thin"] = pct(res.reliable[thin]) if thin.any() else float("nan")
        if ref.vertex_areas is not None:
            large = ref.vertex_areas > np.percentile(ref.vertex_areas, 75)
            m["large_share"] = 100.0 * ref.vertex_areas[large].sum() / ref.vertex_areas.sum()
            m["area_large"] = 100.0 * (res.area[large].sum() / ref.vertex_areas[large].sum() - 1.0)
            for name, sel in (("thin", thin), ("thick", ~thin)):
                m[f"area_{name}"] = 100.0 * (res.area[sel].sum() / ref.vertex_areas[sel].sum() - 1.0)
    for name, sel in case.regions.items():
        m.setdefault("regions", []).append((name, int(sel.sum()), pct(dots[sel & ok] > 0), pct(res.reliable[sel]),
                                            int((wrong & sel).sum())))
    m["ref_area"] = ref.area
    if ref.vertex_areas is not None and np.isfinite(ref.area):
        used = has
        m["area_used"] = float(res.area[used].sum())
        m["area_unused"] = float(res.area[~used].sum())
        m["n_unused"] = int((~used).sum())
        m["unused_outlier"] = pct(res.outlier[~used]) if (~used).any() else float("nan")
        m["used_outlier"] = pct(res.outlier[used])
        m["area_max_ratio"] = float(res.area.max() / np.median(res.area[res.reliable]))
        if ref.boundary is not None:
            split = (("mesh vertices off its boundary", used & ~ref.boundary),
                     ("mesh vertices on its boundary", used & ref.boundary),
                     ("in no triangle, not outliers", ~used & ~res.outlier),
                     ("in no triangle, outliers", ~used & res.outlier),
                     ("mesh vertices flagged outliers", used & res.outlier))
            m["area_split"] = [(name, int(sel.sum()), float(res.area[sel].sum()), float(ref.vertex_areas[sel].sum()))
                               for name, sel in split]
    # mean curvature: one global flip aligns heatcurv's sign with the mesh's normals
    h_ref = ref.mean
    flip = 1.0 if m["orient"] >= 50.0 else -1.0
    h_est = flip * res.mean
    both = np.isfinite(h_ref) & has & res.reliable
    m["h_points"] = int(both.sum())
    m["h_median_est"] = median(h_est[both])
    m["h_median_ref"] = median(h_ref[both])
    for q in (50, 90):
        clear = both & (np.abs(h_ref) > np.percentile(np.abs(h_ref[both]), q))
        m[f"h_sign{q}"] = pct(np.sign(h_est[clear]) == np.sign(h_ref[clear]))
        m[f"h_clear{q}"] = int(clear.sum())
    m["h_spread"] = float(np.std(h_ref[both]) / np.std(h_est[both]))


def measure_scene(case: Case, res, feats, m: dict) -> None:
    scene = case.scene
    has = np.isfinite(scene.normals).all(axis=1)
    exact = np.where(has[:, None], scene.normals, 0.0)
    ok = has & ~res.outlier
    dots = np.einsum("ij,ij->i", res.normals, exact)
    angles = line_angle(res.normals, exact)
    smooth = ok & res.reliable & ~scene.sharp
    m["ref_normals"] = "exact"
    m["orient"] = pct(dots[ok] > 0)
    m["n_oriented"] = int(ok.sum())
    m["wrong"] = int((ok & (dots <= 0)).sum())
    m["wrong_reliable"] = int((ok & (dots <= 0) & res.reliable).sum())
    m["angle"] = median(angles[smooth])
    m["angle95"] = float(np.percentile(angles[smooth], 95))
    m["ref_area"] = float(scene.area)
    classes = []
    for label, name in scene.classes.items():
        sel = scene.labels == label
        row = {"label": label, "name": name, "n": int(sel.sum()), "reliable": pct(res.reliable[sel]),
               "outliers": int(res.outlier[sel].sum()), "features": pct(feats.mask[sel]),
               "orient": float("nan"), "angle": float("nan")}
        if has[sel].any():
            row["orient"] = pct(dots[sel & ok] > 0)
            row["angle"] = median(angles[sel & smooth])
        classes.append(row)
    m["classes"] = classes
    radius = m["radius"]
    for region, sign in (("convex", 1.0), ("concave", -1.0)):
        sel = getattr(scene, region) & res.reliable
        far = sel & (scene.edge_distance > radius)
        m[f"{region}_n"] = int(sel.sum())
        m[f"{region}_sign"] = pct(np.sign(res.mean[sel]) == sign)
        m[f"{region}_far_n"] = int(far.sum())
        m[f"{region}_far_sign"] = pct(np.sign(res.mean[far]) == sign)
        m[f"{region}_median"] = median(res.mean[sel])
        m[f"{region}_exact"] = median(scene.mean[sel])
    m["sharp_n"] = int(scene.sharp.sum())
    m["sharp_recall"] = pct(feats.mask[scene.sharp])
    m["feature_near"] = pct(scene.edge_distance[feats.mask] <= radius)
    m["reliable_near_edge"] = pct(res.reliable[scene.edge_distance <= radius])
    vegetation = [label for label, name in scene.classes.items() if "vegetation" in name]
    if vegetation:
        m["features_in_vegetation"] = pct(np.isin(scene.labels[feats.mask], vegetation))


# ---------------------------------------------------------------------------
# pictures
# ---------------------------------------------------------------------------


def shrink_png(path) -> None:
    """Re-save a PNG with a 256-colour palette (no dithering): a third of the size, no visible change."""
    from PIL import Image

    with Image.open(path) as im:
        quantized = im.convert("RGB").quantize(256, dither=Image.Dither.NONE)
    quantized.save(path, optimize=True)


def render_panels(points, panels, path, size=PICTURE, title=None) -> None:
    """Draw ``panels`` (keyword dicts of :func:`heatcurv.render.render_field`) side by side into one PNG.

    One panel is drawn directly; several are drawn into temporary files of
    ``size[0] / len(panels)`` by ``size[1]`` pixels each and put side by side.
    """
    import matplotlib.image as mpimg

    from heatcurv.render import render_field

    if len(panels) == 1:
        render_field(points, path=path, size=size, title=title, **panels[0])
    else:
        width = size[0] // len(panels)
        pictures = []
        with tempfile.TemporaryDirectory() as tmp:
            for k, panel in enumerate(panels):
                part = Path(tmp) / f"panel{k}.png"
                render_field(points, path=part, size=(width, size[1]), **panel)
                pictures.append(mpimg.imread(part))
        height = max(p.shape[0] for p in pictures)
        pictures = [np.pad(p, ((0, height - p.shape[0]), (0, 0), (0, 0)), constant_values=1.0) for p in pictures]
        mpimg.imsave(path, np.concatenate(pictures, axis=1))
    shrink_png(path)


def make_pictures(case: Case, m: dict, outdir: Path) -> list[tuple[str, str]]:
    """The case's pictures: ``[(file name, caption), ...]``."""
    from heatcurv.render import colour_limits, grey_unreliable

    res, feats = m["res"], m["features"]
    pts = case.points
    n = len(pts)
    made = []
    # unreliable points are drawn grey (NaN), as `heatcurv render` draws them
    shown = grey_unreliable(res.mean, res.reliable)
    grey = f" Grey: the {int(np.count_nonzero(~res.reliable))} unreliable points."
    mean_kw = {"values": shown, "field": "mean", "normals": res.normals, "length_unit": case.unit}
    lit = {"normals": res.normals}  # every panel shaded by, and hiding its far side with, the computed normals

    def out(kind):
        return outdir / f"real_{case.key}_{kind}.png"

    if case.key == "face":
        limits = colour_limits(res.mean[res.reliable], "signed")[:2]
        front = {"view": (0, 0, 1), "up": (0, 1, 0)}
        side = {"view": (np.sin(np.radians(60)), 0, np.cos(np.radians(60))), "up": (0, 1, 0)}
        render_panels(pts, [
            {**mean_kw, **front, "value_range": limits, "title": "face000: mean curvature, from the camera"},
            {**mean_kw, **side, "value_range": limits, "title": "turned 60 degrees"},
        ], out("mean"))
        made.append((out("mean").name, f"face000.ply ({n} points): mean curvature (default run), seen "
                     "from its camera and turned by 60 degrees." + grey))
        flip = 1.0 if m["orient"] >= 50.0 else -1.0
        render_panels(pts, [
            {**mean_kw, "values": flip * res.mean, **front, "value_range": limits,
             "title": "heatcurv's mean curvature"},
            {**mean_kw, "values": case.ref.mean, **front, "value_range": limits,
             "title": "the mesh's cotangent mean curvature"},
        ], out("mesh"))
        made.append((out("mesh").name, "face000.ply: heatcurv's mean curvature (left) and the scanner mesh's "
                     "cotangent mean curvature (right; grey: off the mesh or on its boundary), same colours. The "
                     "stripes on the forehead and cheeks are in both: they are in the scan."))
        render_panels(pts, [
            {"values": feats.mask, "field": "feature", **front, **lit,
             "title": f"face000: sharp features ({int(feats.mask.sum())} points)"},
            {"values": res.reliable, "field": "reliable", **front, **lit, "title": f"reliable ({m['reliable']:.1f} %)"},
        ], out("features"))
        made.append((out("features").name, "face000.ply: the points `sharp_features` flags (left) and the "
                     "reliable points (right), seen from the camera."))
        render_panels(pts, [
            {"values": res.outlier, "field": "outlier", **side, **lit,
             "title": f"face000: outliers ({m['outliers']} points), turned 60 degrees"},
            {"values": res.area, "field": "area", **front, **lit, "length_unit": "mm",
             "title": "area per point (outliers: 0)"},
        ], out("outliers"))
        made.append((out("outliers").name, "face000.ply: the outliers (red; left, turned by 60 degrees so the "
                     "stray points in front of and below the face stand out) and the area per point (right, from "
                     "the camera; outliers get 0, the sparse rims the largest areas)."))
    elif case.key == "lidar":
        view = {"view": (0, -1, 0), "up": (0, 0, 1), "elevation": 40.0, "vertical": "z", "views": 2}
        render_panels(pts, [{**mean_kw, **view}], out("mean"),
                      title=f"LiDAR tile ({n} points): mean curvature, from the south and the north, 40 degrees up")
        made.append((out("mean").name, f"lidar_tile(20000) ({n} points, `orient=\"up\"`): mean curvature, seen "
                     "from the south and from the north, 40 degrees above the horizon." + grey))
        render_panels(pts, [{"values": feats.mask, "field": "feature", **view, **lit}], out("features"),
                      title=f"LiDAR tile: sharp features ({int(feats.mask.sum())} points)")
        made.append((out("features").name, "lidar_tile(20000): the points `sharp_features` flags, same views."))
    elif case.key == "cad":
        view = {"view": (0.5, -1.0, 0.0), "up": (0, 0, 1), "elevation": 35.0, "views": 2}
        render_panels(pts, [{**mean_kw, **view, "value_range": (-0.25, 0.25)}], out("mean"),
                      title=f"CAD part ({n} points): mean curvature, two opposite corners, 35 degrees up")
        made.append((out("mean").name, f"cad_part(20000) ({n} points): mean curvature from two opposite "
                     "corners, 35 degrees up; colour range fixed at +-0.25 /mm (boss +0.083, hole -0.125, the "
                     "edges far beyond)." + grey))
        render_panels(pts, [{"values": feats.mask, "field": "feature", **view, **lit}], out("features"),
                      title=f"CAD part: sharp features ({int(feats.mask.sum())} points)")
        made.append((out("features").name, "cad_part(20000): the points `sharp_features` flags, same views."))
    elif case.key != "face_camera":
        render_panels(pts, [{**mean_kw, "views": 2}], out("mean"),
                      title=f"{case.title} ({n} points): mean curvature, seen from both sides")
        made.append((out("mean").name, f"{case.title} ({n} points): mean curvature, seen from both sides." + grey))
    return made


# ---------------------------------------------------------------------------
# formatting
# ---------------------------------------------------------------------------


def fmt(v, digits=3) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    if isinstance(v, (int, np.integer)):
        return f"{int(v):,}"
    if isinstance(v, str):
        return v
    if v == 0:
        return "0"
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    return f"{v:.{digits}g}"


def pfmt(v, decimals=1) -> str:
    """A percentage with fixed decimals (100.0, 99.8, 4.3)."""
    if v is None or not np.isfinite(v):
        return "-"
    return f"{v:.{decimals}f}"


def signed_pct(v) -> str:
    return "-" if v is None or not np.isfinite(v) else f"{v:+.1f}"


def table(title: str, header: list[str], rows: list[list[str]], markdown: bool) -> str:
    return text_table(title, header, rows, markdown, heading="**{}**")


def tables(cases: list[Case], results: dict, markdown: bool) -> str:
    blocks = []
    rows = []
    for c in cases:
        m = results[c.key]
        rows.append([c.title, fmt(m["n"]), m["orient_mode"], f"{m['seconds']:.2f}", fmt(m["spacing"]), m["kernel"],
                     fmt(m["radius"]),
                     fmt(m["components"]), fmt(m["ambiguous"]), fmt(m["outliers"]), pfmt(m["reliable"]),
                     fmt(m["n_features"])])
    blocks.append(table("Runs: heatcurv.estimate on the whole cloud", [
        "scan", "points", "orient", "time s", "spacing", "kernel", "ball radius", "components", "ambiguous",
        "outliers",
        "reliable %", "features"], rows, markdown))

    rows = []
    for c in cases:
        m = results[c.key]
        if "orient" not in m:
            continue
        rows.append([c.title, m["ref_normals"], fmt(m["n_oriented"]), pfmt(m["orient"], 2), fmt(m["wrong"]),
                     fmt(m["wrong_reliable"]), pfmt(m.get("thin", float("nan"))),
                     pfmt(m.get("wrong_thin", float("nan"))), f"{m['angle']:.2f}", f"{m['angle95']:.2f}",
                     pfmt(m.get("facing_camera", float("nan")), 2)])
    if rows:
        blocks.append(table("Normals against the reference normals", [
            "scan", "reference", "points", "same side %", "wrong side", "of them reliable", "thin %",
            "wrong side: thin %", "median angle deg", "95th pct deg", "facing camera %"], rows, markdown))

    rows = []
    for c in cases:
        m = results[c.key]
        ref = m.get("ref_area", float("nan"))
        if not np.isfinite(ref):
            continue
        rows.append([c.title, fmt(ref, 5), fmt(m["area_total"], 5), signed_pct(100 * (m["area_total"] / ref - 1)),
                     fmt(m["area_reliable"], 5), signed_pct(100 * (m["area_reliable"] / ref - 1)),
                     signed_pct(m.get("area_thin", float("nan"))), signed_pct(m.get("area_thick", float("nan"))),
                     pfmt(m.get("large_share", float("nan"))), signed_pct(m.get("area_large", float("nan")))])
    if rows:
        blocks.append(table("Total area against the reference area", [
            "scan", "reference", "sum of areas", "diff %", "reliable only", "diff %", "thin parts diff %",
            "elsewhere diff %", "largest quarter: share %", "diff %"], rows, markdown))

    rows = []
    for c in cases:
        m = results[c.key]
        if c.key == "face_camera" and "face" in results:  # the same areas as the outward run
            continue
        for name, count, est, mesh in m.get("area_split", []):
            rows.append([c.title, name, fmt(count), fmt(est, 5), fmt(mesh, 5)])
    if rows:
        blocks.append(table("Where the range map's area is", [
            "scan", "points", "count", "heatcurv area", "mesh vertex area"], rows, markdown))

    rows = [[c.title, fmt(results[c.key]["half_n"]), pfmt(results[c.key]["half_orient"], 2),
             signed_pct(results[c.key]["half_area"]), results[c.key]["half_kernel"],
             fmt(results[c.key]["half_radius"]), pfmt(results[c.key].get("half_thin", float("nan"))),
             f"{results[c.key]['half_seconds']:.2f}"] for c in cases]
    blocks.append(table("A random half against the whole", [
        "scan", "points", "same side %", "total area diff %", "kernel", "ball radius", "thin %", "time s"], rows,
        markdown))

    rows = []
    for c in cases:
        m = results[c.key]
        if "h_sign50" not in m:
            continue
        rows.append([c.title, fmt(m["h_points"]), fmt(m["h_median_est"]), fmt(m["h_median_ref"]),
                     f"{m['h_spread']:.2f}", pfmt(m["h_sign50"]), pfmt(m["h_sign90"])])
    if rows:
        blocks.append(table("Mean curvature against the mesh's cotangent mean curvature (reliable points)", [
            "scan", "points", "median H heatcurv", "median H mesh", "spread mesh/heatcurv",
            "same sign %, upper half of mesh abs(H)", "same sign %, top 10 %"], rows, markdown))

    rows = []
    for c in cases:
        m = results[c.key]
        for row in m.get("classes", []):
            rows.append([c.title, f"{row['name']} ({row['label']})", fmt(row["n"]), pfmt(row["orient"], 2),
                         fmt(row["angle"]), pfmt(row["reliable"]), fmt(row["outliers"]), pfmt(row["features"])])
    if rows:
        blocks.append(table("Scenes: per class, against the exact normals", [
            "scene", "class", "points", "same side %", "median angle deg", "reliable %", "outliers",
            "features %"], rows, markdown))

    rows = []
    for c in cases:
        m = results[c.key]
        if "convex_sign" not in m:
            continue
        rows.append([c.title, fmt(m["convex_n"]), pfmt(m["convex_sign"]), pfmt(m["convex_far_sign"]),
                     fmt(m["convex_median"]), fmt(m["convex_exact"]), fmt(m["concave_n"]), pfmt(m["concave_sign"]),
                     pfmt(m["concave_far_sign"]), fmt(m["concave_median"]), fmt(m["concave_exact"]),
                     fmt(m["sharp_n"]), pfmt(m["sharp_recall"]), pfmt(m["feature_near"])])
    if rows:
        blocks.append(table("Scenes: curvature sign (reliable points) and sharp features", [
            "scene", "convex pts", "H > 0 %", "beyond 1 ball %", "median H", "exact", "concave pts", "H < 0 %",
            "beyond 1 ball %", "median H", "exact", "sharp pts", "recall %", "flagged near edge %"], rows, markdown))
    return "\n".join(blocks)


def machine() -> list[str]:
    mem = memory_text()
    import numba

    return [
        f"date (UTC)   {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}",
        f"machine      {cpu_model()}, {os.cpu_count()} cores{mem}; {platform.system()} {platform.release()}",
        f"python       {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"numba {numba.__version__}",
        f"heatcurv     {heatcurv.__version__} (commit {commit()})",
    ]


# ---------------------------------------------------------------------------
# the page
# ---------------------------------------------------------------------------


def page(cases: list[Case], results: dict, pictures: list, info: list[str], wall: float, load, args,
         closed=None) -> str:
    r = results
    by_key = {c.key: c for c in cases}
    lines = [
        "# heatcurv on real scans",
        "",
        "What to expect when you run heatcurv on a scan: pictures of the mean curvature and of the flags",
        "on real range scans and models, and checks that need no exact curvature, measured by",
        "`benchmarks/real_scans.py`. The scans come with meshes (the scanner's triangulation or the",
        "modeller's), and the meshes are the reference: their vertex normals, their area and their",
        "cotangent mean curvature. heatcurv is given only the vertices, as a point cloud. Two simulated",
        "scenes with known answers stand in for data no mesh describes: an aerial LiDAR tile (with",
        "vegetation) and a CAD part with sharp edges.",
        "",
        "## The scans",
        "",
        "| scan | what it is | points | where it comes from |",
        "|---|---|---|---|",
    ]
    source = {
        "bunny": "pymeshlab sample `bunny.obj`", "face": "pymeshlab sample `rangemaps/face000.ply`",
        "face_camera": "the same file; the camera is its `camera` element (`range_camera`)",
        "bone": "pymeshlab sample `bone.ply`", "cow": "pymeshlab sample `cow.obj`",
        "airplane": "pymeshlab sample `airplane.obj`",
        "bunny1839": "shipped with heatcurv: `heatcurv/data/bunny_scan_1839.ply`",
        "lidar": "`heatcurv.surfaces.lidar_tile(20000, seed=0)`", "cad": "`heatcurv.surfaces.cad_part(20000)`",
    }
    for c in cases:
        lines.append(f"| {c.title} | {c.what} | {fmt(len(c.points))} | {source[c.key]} |")
    lines += [
        "",
        "pymeshlab's sample meshes are GPL-3, so heatcurv does not ship them: the script, like the tests in",
        "`tests/real/`, fetches them at run time with `fetch_pymeshlab_samples()` of `tests/support/scans.py`,",
        "which downloads the pinned pymeshlab wheel with pip, checks its SHA-256, keeps only the sample",
        "meshes in a cache directory (`$HEATCURV_TEST_DATA`, else `~/.cache/heatcurv/test-data/`) and",
        "deletes the wheel. The pictures on this page are renderings of heatcurv's output on them.",
        "",
    ]
    models = [c for c in cases if c.n_vertices > len(c.points)]
    if models:
        lines += [
            "The low-poly models hold vertices that no triangle uses ("
            + "; ".join(f"{c.title}: {fmt(len(c.points))} used of {fmt(c.n_vertices)}" for c in models)
            + "); the cloud is the used vertices, the points of the surface.",
            "",
        ]
    if "bunny1839" in by_key and "residual" in r["bunny1839"]:
        med, p99 = r["bunny1839"]["residual"]
        lines += [
            "The shipped 1839-point bunny has no mesh of its own. It is a decimated scan of the same bunny,",
            "so `bunny.obj` is moved onto it (scale, rotation and shift fitted by closest-point iterations)",
            f"and read at each point's nearest vertex: the points lie {fmt(med)} (median; 99th percentile",
            f"{fmt(p99)}) from a vertex, against a point spacing of {fmt(r['bunny1839']['spacing'])} (median distance",
            "to the nearest point). Its area is not compared: the scan has holes and an open base, the mesh",
            "is closed.",
            "",
        ]
    lines += [
        "## How the numbers were measured",
        "",
        "```",
        f"python benchmarks/real_scans.py {' '.join(args.argv_shown)}".rstrip(),
        "```",
        "",
        *[f"    {line}" for line in info],
        f"    load         1-minute load average {load[0]:.1f} at the start, {load[1]:.1f} at the end",
        "",
        f"The whole run took {wall:.0f} s (estimates, their random halves, the pictures). `time s` is the",
        "wall time of one `heatcurv.estimate` call with default options, numba compiled beforehand. The",
        "machine is shared: with other jobs running (the load above; 2 cores) times vary by up to about",
        "two-fold from run to run; the other numbers do not depend on it.",
        "",
        "* **spacing**: the median distance from a point to its nearest neighbour, in the scan's units.",
        "* **ball radius**: the median radius of the ball heatcurv fitted each point's surface in",
        "  (`res.info[\"scale\"].median_radius`), in the scan's units. Anything thinner than this, or",
        "  curved on a smaller scale, is smoothed over.",
        "* **same side %**: of the points with a reference normal that are not outliers, the share whose",
        "  estimated normal is on the same side as the reference: the mesh's area-weighted vertex normal",
        "  (outward on the closed meshes, towards the camera on the range map) or the scene's exact normal.",
        "  **wrong side** counts the others, **of them reliable** those among them flagged reliable.",
        "* **thin %**: points whose ball (of the median radius) reaches the other side of the closed mesh,",
        "  a vertex whose normal is more than 120 degrees from the point's, as across a leg, an ear or a",
        "  wing. **wrong side: thin %** is the share of the wrong-side points that are thin.",
        "* **median angle**: between the estimated and the reference normal *lines* (orientation aside), on",
        "  the reliable points (on the scenes also away from the sharp edges); 95th percentile beside it.",
        "* **total area**: the sum of `res.area` against the mesh's area (the CAD part: its exact area);",
        "  \"reliable only\" sums the reliable points' areas; \"thin parts\" and \"elsewhere\" compare",
        "  heatcurv's areas of the thin and the other points with the mesh's vertex areas of the same points;",
        "  \"largest quarter\" is the quarter of the vertices with the largest mesh vertex areas (the largest",
        "  triangles): their share of the mesh's area, and heatcurv's area of the same points against it.",
        f"* **random half**: the points with `np.random.default_rng({args.seed}).random(n) < 0.5`, estimated on",
        "  their own: % of their normals (outliers of either run left out) on the same side as in the whole",
        "  cloud, and the difference of the total areas (the same surface, sampled half as densely).",
        "* **mean curvature**: the mesh's cotangent mean curvature `H = -(Delta x . n) / 2` at the vertices",
        "  off the mesh's boundary against heatcurv's at the same reliable points, heatcurv's sign aligned",
        "  with the mesh's normals by one global flip. The cotangent formula is noisy vertex by vertex",
        "  (\"spread\" is the ratio of the standard deviations), so only the medians and the signs are",
        "  compared: where the mesh's `|H|` is above its median, and in its top 10 %.",
        "* **scenes**: the sign of the mean curvature on the reliable points of the regions where it is",
        "  known to be positive (hill top; CAD boss) and negative (valley floor; CAD hole), also only",
        "  beyond one ball radius from a sharp edge; the share of the points within 0.5 (m; mm) of a sharp",
        "  edge that `sharp_features` flags (recall); \"flagged near edge\" is the share of the flagged",
        "  points within one ball radius of an edge.",
        "",
        "## Measured checks",
        "",
        tables(cases, results, markdown=True),
    ]
    warned = [(c.title, w) for c in cases for w in r[c.key]["warnings"]]
    lines += ["Warnings during the runs: " + ("none." if not warned else ""), ""]
    lines += [f"* {t}: {w}" for t, w in warned] + ([""] if warned else [])
    if closed:
        lines += [
            "## Closed objects with thin parts",
            "",
            "CGAL's twelve closed models (animals and figures with legs, ears, tails and horns; lion has small",
            "holes), their used vertices as the cloud and the meshes' outward vertex normals as the truth, with",
            "the default options: the share of points whose normal points into the object, on parts at least",
            "3 spacings thick, inside out *and* flagged reliable (the silent error), and flagged. The same",
            "table with noisy and half-sampled variants, tiled runs and Open3D's orientation beside it is in",
            "[orientation.md](orientation.md) (`benchmarks/orientation.py`).",
            "",
            text_table("", CLOSED_COLUMNS, closed, True, heading="{}").strip(),
            "",
        ]
    if pictures:
        lines += [
            "## Pictures",
            "",
            "Mean curvature: blue negative, red positive, near white at zero (the colour bar symmetric about 0",
            "where the values change sign), clipped at the 2nd and 98th percentiles (arrows: values beyond);",
            "unreliable points mid grey. Masks: the flagged points red. Every picture is lit from the normals.",
            "",
        ]
        for name, caption in pictures:
            lines += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    lines += explain(cases, results)
    return "\n".join(lines).rstrip() + "\n"


def explain(cases, r) -> list[str]:
    """Plain words about the flags and what the numbers say, with the measured numbers."""
    by_key = {c.key: c for c in cases}

    def diff(a, b):
        return signed_pct(100.0 * (a / b - 1.0))

    lines = [
        "## What `reliable`, `outlier` and `orient` mean on these scans",
        "",
        "* **`res.outlier`**: points no surface explains: the stray points of a range scan (small",
        "  islands, veils of mixed pixels at depth jumps, points much sparser than their ball). They get",
        "  area 0, are never reliable and weigh nothing in their neighbours' fits. Their other fields are",
        "  still filled in: ignore them.",
        "* **`res.reliable`**: heatcurv trusts the point's values: not an outlier, not on a border of the",
        "  scan, its ball a surface, the fit well posed, the normal consistently oriented. Use the reliable",
        "  points for statistics. Expect unreliable points on rims, at holes and where the sampling is",
        "  too coarse, along sharp edges and in vegetation (where the fit's residual is many times the",
        "  cloud's median). `reliable` is not a promise, though: see the limitations below (thin parts).",
        "* **`orient`**: which side the normals point to, and with them the sign of the curvatures",
        "  (positive mean curvature: the surface bends away from its normal, like a sphere with outward",
        "  normals). The default, `\"auto\"`, orients an open surface over the horizontal plane `\"up\"`",
        "  and anything else `\"outward\"` ([orientation.md](orientation.md)). `\"outward\"` carries one side",
        "  from neighbour to",
        "  neighbour over each connected piece and turns the piece to point away from the volume it",
        "  encloses; on a closed cloud the generalised winding number of the whole cloud then turns the",
        "  parts the first step turned inside out (legs, ears) and flags the points whose side it",
        "  contradicts ([orientation.md](orientation.md), with a table over twelve closed animal models",
        "  beside Open3D's orientation). `\"up\"` (aerial and terrain data) and `viewpoint=` (a scanner",
        "  position) set every normal that clearly faces +z or the scanner (or clearly faces away) on",
        "  its own, and give the others (walls, grazing views) the side of the nearest such point.",
        "  Points found to have no consistent side are counted `ambiguous` in",
        "  `res.info[\"orientation\"]` and left unreliable; the cow and the small bunny below show that",
        "  not every wrong side is found.",
        "",
        "## What the numbers say",
        "",
    ]
    if "bunny" in r:
        m = r["bunny"]
        lines.append(
            f"* **bunny.obj** (closed range scan, {fmt(m['n'])} points, {m['seconds']:.1f} s): "
            f"{pfmt(m['orient'], 2)} % of the normals point outward like the mesh's, {fmt(m['wrong'])} do not; "
            f"the median angle to the mesh's normals is {m['angle']:.2f} degrees; the total area is "
            f"{diff(m['area_total'], m['ref_area'])} % off the mesh's; {pfmt(m['reliable'])} % reliable, "
            f"{m['outliers']} outliers. The median mean curvature is {fmt(m['h_median_est'])} against the "
            f"mesh's {fmt(m['h_median_ref'])}, and the signs agree on {pfmt(m['h_sign50'])} % of the points "
            f"where the mesh's curvature is above its median, {pfmt(m['h_sign90'])} % in its top 10 %. A clean,"
            " dense, closed scan: this is heatcurv at its best.")
    if "face" in r:
        m = r["face"]
        split = {name: (count, est, mesh) for name, count, est, mesh in m.get("area_split", [])}
        lines.append(
            f"* **face000.ply** (one range map, {fmt(m['n'])} points, {m['seconds']:.1f} s): {fmt(m['n_unused'])} "
            f"points lie in no triangle of the scanner's mesh (stray points). heatcurv flags {fmt(m['outliers'])} "
            f"points as outliers: {pfmt(m['unused_outlier'])} % of the strays and {pfmt(m['used_outlier'], 2)} % "
            f"of the mesh's vertices. Without a camera the default orients the face up (+z), a surface over the "
            "horizontal plane; "
            f"{pfmt(m['orient'], 2)} % face the camera's side like the mesh's; of the {fmt(m['wrong'])} that "
            f"do not, {fmt(m.get('wrong_small_pieces', 0))} lie in the mesh's smaller pieces (islands apart from "
            f"the face, oriented on their own). {pfmt(m['reliable'])} % of the points are reliable: the others "
            "are the rims, the edges of the holes and the outliers (see the pictures). The mean curvature's "
            f"signs agree with the mesh's on {pfmt(m['h_sign50'])} % of the points above the mesh's median "
            f"`|H|` and on {pfmt(m['h_sign90'])} % in its top 10 %. The mesh's vertex curvature is "
            f"{m['h_spread']:.1f} times as spread as heatcurv's: the cotangent formula is noisy vertex by vertex "
            "and heatcurv's ball smooths over about "
            f"{m['radius'] / m['spacing']:.0f} spacings (radius {fmt(m['radius'])} mm), so the signs differ "
            "mostly where the curvature is weak (see the comparison picture). `sharp_features` flags "
            f"{fmt(m['n_features'])} points ({pfmt(100 * m['n_features'] / m['n'])} %): on a face these are "
            "creases (eyelids, the headband's edges, the beard) and scattered speckle, not machined edges.")
        if split:
            off, on = split.get("mesh vertices off its boundary"), split.get("mesh vertices on its boundary")
            stray = split.get("in no triangle, not outliers")
            lines.append(
                f"* **The face's area exceeds its mesh's.** The mesh's area is {fmt(m['ref_area'], 5)} mm²; "
                f"heatcurv's total is {fmt(m['area_total'], 5)} mm² ({diff(m['area_total'], m['ref_area'])} %), "
                f"the reliable points' {fmt(m['area_reliable'], 5)} mm² "
                f"({diff(m['area_reliable'], m['ref_area'])} %). On the mesh's vertices off its boundary the two "
                f"agree ({fmt(off[1], 5)} against {fmt(off[2], 5)} mm², {diff(off[1], off[2])} %); the excess is "
                f"on the mesh's boundary vertices ({fmt(on[1], 4)} against {fmt(on[2], 4)} mm²) and on the "
                f"{fmt(stray[0])} stray points heatcurv keeps ({fmt(stray[1], 4)} mm²). The scanner's mesh leaves "
                "out the sparse rims (its triangles stop where the samples thin out) and the gaps in it, while "
                "heatcurv gives every surface point the area around it. The largest area of one point is "
                f"{m['area_max_ratio']:.0f} times the median reliable one (a sparse rim point).")
    if "face_camera" in r:
        m = r["face_camera"]
        lines.append(
            f"* **face000.ply with its camera** (`viewpoint=range_camera(path)`, {m['seconds']:.1f} s): "
            f"{pfmt(m['facing_camera'], 2)} % of all normals face the camera and {pfmt(m['orient'], 2)} % are on "
            f"the mesh's side ({fmt(m['wrong'])} wrong, against {fmt(r['face']['wrong']) if 'face' in r else '-'} "
            "without the camera). If you know where the scanner stood, give it: it settles the side of every "
            "piece, islands included.")
    models = [k for k in ("bone", "cow", "airplane") if k in r]
    if models:
        parts = []
        for k in models:
            m = r[k]
            parts.append(
                f"{by_key[k].title}: {fmt(m['n'])} points, same side {pfmt(m['orient'], 2)} %, median angle "
                f"{m['angle']:.2f} degrees, area {diff(m['area_total'], m['ref_area'])} %, reliable "
                f"{pfmt(m['reliable'])} %, {fmt(m['ambiguous'])} ambiguous")
        lines.append(
            "* **The low-poly models** (" + "; ".join(parts) + "). Their vertices are a modeller's, not a "
            "scanner's: a few thousand of them, unevenly spaced, so the ball is wide compared with thin parts "
            "(legs, wings, the tail plane).")
    if "cow" in r:
        m = r["cow"]
        others = [k for k in ("bunny", "bone", "airplane") if k in r and "large_share" in r[k]]
        lines.append(
            f"* **cow.obj is the hard case.** Only {pfmt(m['orient'], 1)} % of its normals are on the mesh's "
            f"outward side: {fmt(m['wrong'])} points are inward, and {fmt(m['wrong_reliable'])} of them are "
            f"nevertheless flagged reliable. {pfmt(m['wrong_thin'])} % of the inward points are thin: their ball "
            f"(median radius {fmt(m['radius'])}; the cow is {fmt(float(np.ptp(by_key['cow'].points[:, 2])))} "
            "long) reaches the other side of a leg or an ear, so the two sides are one blur to the fit "
            f"and the side cannot be carried along. {pfmt(m['thin'])} % of the cow's points are thin in this "
            "sense; being thin does not always flip normals (airplane.obj's wings are thin too and all its "
            f"normals are right), but nearly every flip here ({pfmt(m['wrong_thin'])} %) is in a thin part. The "
            f"mean curvature's signs follow: {pfmt(m['h_sign50'])} % agree above the mesh's median `|H|`, "
            f"{pfmt(m['h_sign90'])} % in its top 10 %. The "
            f"area is {diff(m['area_total'], m['ref_area'])} % off, and not on the thin parts "
            f"({signed_pct(m['area_thin'])} %; elsewhere {signed_pct(m['area_thick'])} %): the quarter of the "
            f"vertices with the largest triangles carries {pfmt(m['large_share'])} % of the mesh's area, and "
            f"heatcurv's area of those points is {signed_pct(m['area_large'])} % off" + (
                " (on " + ", ".join(f"{by_key[k].title} {pfmt(r[k]['large_share'])} % of the area, "
                                    f"{signed_pct(r[k]['area_large'])} %" for k in others) + ")" if others else "")
            + ". heatcurv's areas come from the density of points in the ball, which smooths over the jumps "
            "between large and small triangles; on the cow, with most of its area in large triangles, that "
            "counts. Such models need more, and more even, points: several across a leg.")
    if "airplane" in r:
        m = r["airplane"]
        lines.append(
            f"* **airplane.obj's random half** ({fmt(m['half_n'])} points) comes out {signed_pct(m['half_area'])} % "
            f"in area against the whole cloud: its kernel widened to {m['half_kernel']} (ball radius "
            f"{fmt(m['half_radius'])}, against {fmt(m['radius'])} for the whole), and at that radius "
            f"{pfmt(m.get('half_thin', float('nan')))} % of its points are thin (against {pfmt(m.get('thin'))} % "
            "in the whole cloud). Small clouds of thin shapes are where heatcurv's areas are least dependable.")
    if "bunny1839" in r:
        m = r["bunny1839"]
        ears = next((x for x in m.get("regions", []) if x[0].startswith("ears")), None)
        text = (f"* **The shipped bunny** ({fmt(m['n'])} points, {m['seconds']:.2f} s): {pfmt(m['orient'], 2)} % of "
                f"its normals are on the registered mesh's outward side; {fmt(m['wrong'])} are inward, "
                f"{fmt(m['wrong_reliable'])} of them flagged reliable, {pfmt(m['wrong_thin'])} % of them thin. ")
        if ears:
            text += (f"{fmt(ears[4])} of them are on the ears: of the {fmt(ears[1])} points above y = 6.5, only "
                     f"{pfmt(ears[2])} % are on the right side ({pfmt(ears[3])} % reliable). ")
        text += (f"The ball's median radius is {fmt(m['radius'])} ({m['radius'] / m['spacing']:.0f} spacings; the "
                 "bunny is about 10 across), wider than an ear is thick: at 1839 points the ears are below the "
                 "resolution of the estimate, and the ears' colours in its picture are not to be trusted (an "
                 "inward normal flips the sign of the curvature). The mean-curvature comparison "
                 f"({pfmt(m['h_sign50'])} % same sign) sets a 1839-point estimate against the curvature of a "
                 "28 088-vertex mesh, two different scales: read only the picture's large forms.")
        lines.append(text)
    if "lidar" in r:
        m = r["lidar"]
        cl = {row["label"]: row for row in m["classes"]}
        ground, roof, wall, veg = cl.get(2), cl.get(6), cl.get(66), cl.get(5)
        lines.append(
            f"* **The LiDAR tile** (`orient=\"up\"`, {fmt(m['n'])} points, {m['seconds']:.1f} s): the normals are "
            f"on the sky side on {pfmt(ground['orient'], 2)} % of the ground and {pfmt(roof['orient'], 2)} % of "
            f"the roofs, and out of the building on {pfmt(wall['orient'], 2)} % of the walls (median angles "
            f"{fmt(ground['angle'])}, {fmt(roof['angle'])} and {fmt(wall['angle'])} degrees; the walls are "
            f"sampled five times more sparsely than the ground, {pfmt(wall['reliable'])} % reliable). "
            f"The mean curvature is positive on {pfmt(m['convex_sign'])} % of the hill top (median "
            f"{fmt(m['convex_median'])} /m, exact {fmt(m['convex_exact'])}) and negative on "
            f"{pfmt(m['concave_sign'])} % of the valley floor (median {fmt(m['concave_median'])}, exact "
            f"{fmt(m['concave_exact'])}): the ball (radius {fmt(m['radius'])} m) smooths them a little. "
            f"`sharp_features` flags {pfmt(m['sharp_recall'])} % of the points within 0.5 m of an eave, ridge, "
            "wall corner or wall foot. A random half agrees in side on "
            f"{pfmt(m.get('half_orient_surface', float('nan')), 2)} % of the ground, roof and wall points and on "
            f"{pfmt(m.get('half_orient_volume', float('nan')), 1)} % of the vegetation's.")
        if veg["reliable"] <= 5.0:
            lines.append(
                f"* **Vegetation is volumetric.** The tree crowns are a 3-D scatter of returns, with no surface "
                f"and no true normal. Of their {fmt(veg['n'])} points {pfmt(veg['reliable'])} % are flagged "
                "reliable: the chord fit's residual there is many times the tile's median (no smooth surface "
                f"explains a crown), so they are unreliable; {pfmt(veg['features'])} % are flagged as sharp "
                f"features (they make {pfmt(m.get('features_in_vegetation', float('nan')))} % of all flagged "
                f"points) and {veg['outliers']} are outliers. Mask them with `reliable`, or remove vegetation "
                "by its classification (LAS classes 3-5), before reading curvature or features.")
        else:
            lines.append(
                f"* **Vegetation is volumetric.** The tree crowns are a 3-D scatter of returns, with no surface "
                f"and no true normal. Of their {fmt(veg['n'])} points, {pfmt(veg['reliable'])} % are "
                f"nevertheless flagged reliable, {pfmt(veg['features'])} % are flagged as sharp features (they "
                f"make {pfmt(m.get('features_in_vegetation', float('nan')))} % of all flagged points) and "
                f"{veg['outliers']} are outliers. heatcurv fits a surface through whatever it is given and does "
                "not tell a crown from a roof: remove vegetation by its classification (LAS classes 3-5) before "
                "reading curvature or features, and never read a crown's curvature as a surface's.")
    if "cad" in r:
        m = r["cad"]
        lines.append(
            f"* **The CAD part** ({fmt(m['n'])} points, {m['seconds']:.1f} s): {pfmt(m['orient'], 2)} % of the "
            f"normals point out of the solid, inside the hole too; the area is "
            f"{diff(m['area_total'], m['ref_area'])} % off the exact one. On the boss the mean curvature is "
            f"positive on {pfmt(m['convex_sign'])} % of the reliable points (median {fmt(m['convex_median'])} /mm, "
            f"exact {fmt(m['convex_exact'])}), in the hole negative on {pfmt(m['concave_sign'])} % (median "
            f"{fmt(m['concave_median'])}, exact {fmt(m['concave_exact'])}); beyond one ball radius "
            f"({fmt(m['radius'])} mm) from an edge both are {pfmt(m['convex_far_sign'])} % and "
            f"{pfmt(m['concave_far_sign'])} %. `sharp_features` finds {pfmt(m['sharp_recall'])} % of the points "
            f"within 0.5 mm of an edge, and {pfmt(m['feature_near'])} % of the points it flags are within one "
            "ball radius of one.")
        if m["reliable_near_edge"] < 50.0:
            lines.append(
                "* **Next to a sharp edge the ball holds two faces.** Their mean curvature there is the "
                "crease's, spread over the ball (the saturated bands along the edges in the picture); the fit's "
                "residual shows it, and within one ball radius of the CAD part's edges only "
                f"{pfmt(m['reliable_near_edge'])} % of the points are flagged reliable. The wrong signs on the "
                "boss and in the hole are all in that band. On objects with sharp edges, `sharp_features` "
                "marks the edges themselves.")
        else:
            lines.append(
                "* **Next to a sharp edge, `reliable` does not mean smooth.** Within one ball radius of the CAD "
                f"part's edges {pfmt(m['reliable_near_edge'])} % of the points are flagged reliable, yet their "
                "mean curvature is the crease's, spread over the ball (the saturated bands along the edges in "
                "the picture), and all the wrong signs on the boss and in the hole are in that band. On objects "
                "with sharp edges, use `sharp_features` to mask it.")
    low = [c for c in cases if r[c.key]["half_orient"] < 99.5]
    big = [c for c in cases if abs(r[c.key]["half_area"]) > 5.0]
    lines.append(
        "* **A random half** gives the same sides as the whole on "
        + ", ".join(f"{c.title} {pfmt(r[c.key]['half_orient'], 2)} %" for c in cases)
        + (" (all at least 99.5 %). " if not low else f"; below 99.5 %: {', '.join(c.title for c in low)}. ")
        + "The total area moves by "
        + ", ".join(f"{signed_pct(r[c.key]['half_area'])} %" for c in cases)
        + " (same order): halving the density moves the total area by "
        + (f"at most {max(abs(r[c.key]['half_area']) for c in cases if c not in big):.1f} %" if len(big) < len(cases)
           else "more than 5 %")
        + (f", except on {', '.join(c.title for c in big)} (more than 5 %)." if big else "."))
    lines.append("")
    return lines


# ---------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------


def closed_models(log) -> list[list[str]]:
    """CGAL's twelve closed models (clean): heatcurv's outward orientation against the meshes' normals.

    The rows of ``benchmarks/orientation.py``'s clean table for heatcurv alone (that script adds the
    noisy and half variants, tiled runs and Open3D): model, points, thin %, wrong %, wrong on thick %,
    wrong & reliable %, flagged %.
    """
    import orientation as bench  # benchmarks/orientation.py
    from support.scans import fetch_cgal_meshes

    directory = fetch_cgal_meshes()
    rows, totals = [], []
    for name in bench.MODELS:
        model = bench.load_model(directory, name)
        points, truth, thick = bench.variant(model, "clean")
        res = heatcurv.estimate(points)
        m = bench.measure(res.normals, res.reliable, truth, thick, either_sign=False)
        totals.append((len(points), int(thick.sum()), m))
        rows.append([name + ("" if model["closed"] else " (holes)"), fmt(len(points)),
                     f"{100 * (~thick).mean():.2f}", f"{m['wrong']:.2f}", f"{m['wrong_thick']:.2f}",
                     f"{m['wrong_reliable']:.2f}", f"{m['flagged']:.1f}"])
        log(f"closed {name}: wrong {m['wrong']:.2f} %, wrong & reliable {m['wrong_reliable']:.2f} %")
    n = np.array([t[0] for t in totals], dtype=float)
    nthick = np.array([t[1] for t in totals], dtype=float)

    def pooled(key, weights):
        return float(np.nansum(weights * [t[2][key] for t in totals]) / weights.sum())

    thin = sum(float(r[2]) * w for r, w in zip(rows, n)) / n.sum()
    rows.append(["all", fmt(int(n.sum())), f"{thin:.2f}", f"{pooled('wrong', n):.2f}",
                 f"{pooled('wrong_thick', nthick):.2f}", f"{pooled('wrong_reliable', n):.2f}",
                 f"{pooled('flagged', n):.1f}"])
    return rows


CLOSED_COLUMNS = ["model", "points", "thin %", "wrong %", "wrong on thick %", "wrong & reliable %", "flagged %"]


def parse_args(argv=None):
    p = argparse.ArgumentParser(
        description="heatcurv on real scans (pymeshlab's sample meshes, fetched at run time) and simulated "
        "scenes: checks that need no exact curvature, and pictures.",
        epilog="See the module docstring for the checks.",
    )
    p.add_argument("--only", action="append", choices=CASES, help="run only this scan (repeatable)")
    p.add_argument("--out", metavar="PATH", help="write the page (Markdown) to PATH and its pictures beside it")
    p.add_argument("--no-pictures", action="store_true", help="no PNGs (with --out: a page without pictures)")
    p.add_argument("--data", metavar="DIR", help="directory of the pymeshlab samples (default: the cache)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random half (default 0)")
    p.add_argument("--no-closed", action="store_true",
                   help="skip CGAL's twelve closed models (the orientation table of closed objects with thin parts)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    args = p.parse_args(argv)
    shown = []
    for name in args.only or []:
        shown += ["--only", name]
    if args.out:
        shown += ["--out", args.out]
    if args.no_pictures:
        shown.append("--no-pictures")
    if args.seed:
        shown += ["--seed", str(args.seed)]
    if args.no_closed:
        shown.append("--no-closed")
    args.argv_shown = shown
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    wall = time.perf_counter()
    names = [c for c in CASES if not args.only or c in args.only]

    def log(msg):
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    info = machine()
    load_start = os.getloadavg()[0]
    print("heatcurv on real scans")
    print("\n".join(info))
    print(f"load         1-minute load average {load_start:.1f}")
    print()
    cases = load_cases(names, args.data)
    warm_up()
    results = {}
    for case in cases:
        log(f"{case.key}: {len(case.points)} points {case.options if case.options else ''}")
        results[case.key] = measure(case, args.seed, log)
        for w in results[case.key]["warnings"]:
            log(f"  warning: {w}")
    print(tables(cases, results, markdown=False))
    closed = None if args.no_closed else closed_models(log)
    if closed:
        print(text_table("Closed objects with thin parts (CGAL's models, clean): % of the points inside out",
                         CLOSED_COLUMNS, closed, False))
    for case in cases:
        for name, count, same, reliable, wrong in results[case.key].get("regions", []):
            print(f"{case.title}, {name}: {count} points, same side {same:.2f} %, reliable {reliable:.1f} %, "
                  f"{wrong} on the wrong side")
    pictures = []
    if not args.no_pictures:
        outdir = Path(args.out).parent if args.out else Path(tempfile.mkdtemp(prefix="heatcurv_real_"))
        for case in cases:
            tic = time.perf_counter()
            made = make_pictures(case, results[case.key], outdir)
            pictures += made
            if made:
                log(f"{case.key}: {', '.join(name for name, _ in made)} ({time.perf_counter() - tic:.1f} s)")
        sizes = [(outdir / name).stat().st_size for name, _ in pictures]
        print(f"pictures in {outdir}: {len(pictures)} files, {sum(sizes) / 1e6:.2f} MB")
    seconds = time.perf_counter() - wall
    if args.out:
        text = page(cases, results, pictures, info, seconds, (load_start, os.getloadavg()[0]), args, closed)
        Path(args.out).write_text(text)
        print(f"wrote {args.out}")
    print(f"wall time {seconds:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
