"""Pictures: matplotlib with heatcurv's own shading against PyVista (VTK, off screen), on the same clouds.

heatcurv draws its pictures with matplotlib (:func:`heatcurv.render.render_field`:
discs drawn far to near, lit from the normals, the far side hidden). This
script draws the same clouds with the same camera, colours and limits with
PyVista's off-screen VTK renderer, and measures what choosing one or the other
costs:

* **seconds**: importing the renderer, and drawing and saving the picture
  (the first picture of a process, as ``heatcurv render`` draws it);
* **peak memory**: the process's peak resident set while importing the
  renderer and drawing (``VmHWM`` of ``/proc/self/status``, reset once the
  cloud is loaded), and how far it rises above the resident set with the
  cloud loaded;
* **install weight**: the size of the files pip installed (their ``RECORD``)
  for what each renderer adds to heatcurv's other dependencies: matplotlib
  and what it needs beyond numpy, scipy, numba, ...; PyVista, VTK and what
  they need beyond all of heatcurv's dependencies.

The clouds: a torus (r1 = 1, r2 = 2.3701) of ``--points`` area-uniform random
points (default 1 000 000) with its exact normals and mean curvature (drawn
whole: ``max_points`` is the cloud's size), the same torus with
``render_field``'s default subset of 200 000 points, and the Stanford bunny
scan shipped with heatcurv (1839 points; normals and mean curvature estimated,
unreliable points grey). Every measurement runs in a fresh process, one at a
time, ``--repeat`` times (the fastest run is shown: other work on a shared
machine only slows a run down). The pictures go to ``--out`` (default ``/tmp/heatcurv_pictures``) as
``{cloud}_{renderer}.png`` for a look side by side.

PyVista is not a heatcurv dependency: ``pip install pyvista`` before running.
On a machine without a display VTK renders off screen through EGL (Mesa's
software rasteriser, llvmpipe, here) or OSMesa; when it cannot, the row says
why. The table printed is the one in ``docs/pictures.md``.

Usage::

    python benchmarks/pictures.py                   # the table, pictures in /tmp/heatcurv_pictures
    python benchmarks/pictures.py --points 200000   # a quicker run
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: Picture size of every drawing, pixels.
SIZE = (1400, 1000)
#: The renderers compared: heatcurv's, PyVista lighting its points as spheres, PyVista with heatcurv's lighting.
RENDERERS = ("matplotlib", "pyvista", "pyvista-shaded")
#: Camera tilt of the torus pictures (as ``heatcurv demo`` draws the torus), degrees.
TORUS_ELEVATION = 35.0


def _memory_mb(key: str) -> float:
    """``VmRSS`` (resident now) or ``VmHWM`` (peak resident) of this process from /proc, MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError(f"no {key} in /proc/self/status")


def _reset_peak() -> None:
    """Start the peak resident set (``VmHWM``) again from the resident set now (Linux 4.0 and later)."""
    Path("/proc/self/clear_refs").write_text("5")


def load(cloud: str, n: int) -> dict:
    """The cloud to draw: points, normals, values, title, elevation and points drawn at most."""
    import heatcurv
    from heatcurv import surfaces

    if cloud.startswith("torus"):
        sample = surfaces.Torus().sample(n, "random", seed=0)
        drawn = n if cloud == "torus" else 200_000
        return {"points": sample.points, "normals": sample.normals, "values": sample.mean,
                "title": f"torus, {n:,} random points, exact mean curvature", "elevation": TORUS_ELEVATION,
                "max_points": drawn, "views": 1}
    from heatcurv.data import load_bunny

    points = np.asarray(load_bunny().points, dtype=np.float64)
    res = heatcurv.estimate(points)
    return {"points": points, "normals": res.normals, "values": np.where(res.reliable, res.mean, np.nan),
            "title": f"Stanford bunny scan, {len(points)} points, mean curvature", "elevation": 0.0,
            "max_points": len(points), "views": 1}


def draw_matplotlib(data: dict, path: Path) -> dict:
    """``render_field`` as ``heatcurv render`` calls it."""
    tic = time.perf_counter()
    import matplotlib.backends.backend_agg  # noqa: F401  (what render_field imports)
    import matplotlib.figure  # noqa: F401

    from heatcurv.render import render_field

    imported = time.perf_counter() - tic
    tic = time.perf_counter()
    out = render_field(
        data["points"], data["values"], path, field="mean", size=SIZE, normals=data["normals"],
        elevation=data["elevation"], max_points=data["max_points"], title=data["title"],
    )
    return {"import_s": imported, "draw_s": time.perf_counter() - tic, "drawn": out.drawn}


def draw_pyvista(data: dict, path: Path, light: str = "vtk") -> dict:
    """The same cloud, camera, colours, limits and disc size through PyVista off screen.

    The points are round (``render_points_as_spheres``) and hidden behind
    nearer ones by VTK's depth buffer. ``light="vtk"``: each point is a small
    sphere lit by VTK's light kit, as PyVista draws point clouds;
    ``light="heatcurv"``: the colours lit from the normals by
    :func:`heatcurv.shading.shade_colours` as ``render_field`` lights them,
    drawn unlit.
    """
    tic = time.perf_counter()
    import pyvista as pv

    imported = time.perf_counter() - tic
    from heatcurv.render import (
        MISSING_COLOUR,
        UNDERLAY,
        _colour_mapping,
        _disc_diameter,
        camera_frames,
        colour_limits,
        field_style,
    )
    from heatcurv.shading import shade_colours

    tic = time.perf_counter()
    points, normals, values = data["points"], data["normals"], data["values"]
    if len(points) > data["max_points"]:  # a seeded subset of as many points as render_field draws
        keep = np.sort(np.random.default_rng(0).choice(len(points), data["max_points"], replace=False))
        points, normals, values = points[keep], normals[keep], values[keep]
    low, high, kind = colour_limits(values, field_style("mean").kind)
    colour_map, norm = _colour_mapping(kind, low, high)
    frame = camera_frames(points, 1, normals=normals, elevation=data["elevation"])[0]
    bar = {"title": field_style("mean").bar_label(), "vertical": True, "color": "black",
           "position_x": 0.86, "position_y": 0.15, "height": 0.7, "width": 0.05}
    plotter = pv.Plotter(off_screen=True, window_size=SIZE)
    plotter.set_background("white")
    plotter.enable_parallel_projection()
    cloud = pv.PolyData(points)
    if light == "heatcurv":
        rgba = shade_colours(colour_map(norm(np.ma.masked_invalid(values))), normals @ frame.T)
        cloud.point_data["rgb"] = np.round(255 * rgba[:, :3]).astype(np.uint8)
        actor = plotter.add_mesh(cloud, scalars="rgb", rgb=True, lighting=False, style="points",
                                 render_points_as_spheres=True)
        legend = pv.PolyData(points[:1])  # an invisible point that carries the colour bar
        legend.point_data["mean"] = values[:1]
        plotter.add_mesh(legend, scalars="mean", cmap=colour_map, clim=(low, high), opacity=0.0,
                         scalar_bar_args=bar)
    else:
        cloud.point_data["mean"] = values
        actor = plotter.add_mesh(cloud, scalars="mean", cmap=colour_map, clim=(low, high), nan_color=MISSING_COLOUR,
                                 style="points", render_points_as_spheres=True, scalar_bar_args=bar)
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    radius = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    plotter.camera.focal_point = centre
    plotter.camera.position = centre + 3.0 * radius * frame[2]
    plotter.camera.up = frame[1]
    plotter.reset_camera()
    plotter.camera.zoom(1.2)
    # discs as wide as render_field's wide (underlay) discs, in pixels of this zoom: no gaps
    pixels = SIZE[1] / (2.0 * plotter.camera.parallel_scale)
    actor.prop.point_size = float(np.clip(UNDERLAY * _disc_diameter(points) * pixels, 1.0, 80.0))
    plotter.add_text(data["title"], position="upper_edge", color="black", font_size=12)
    plotter.screenshot(str(path))
    window = type(plotter.ren_win).__name__
    plotter.close()
    return {"import_s": imported, "draw_s": time.perf_counter() - tic, "drawn": len(points), "window": window}


def one(renderer: str, cloud: str, n: int, out: Path) -> dict:
    """Draw one cloud with one renderer in this process; the measurements as a dict."""
    data = load(cloud, n)
    base = _memory_mb("VmRSS")
    _reset_peak()
    path = out / f"{cloud}_{renderer}.png"
    try:
        if renderer == "matplotlib":
            result = draw_matplotlib(data, path)
        else:
            result = draw_pyvista(data, path, "heatcurv" if renderer == "pyvista-shaded" else "vtk")
    except Exception as exc:  # reported in the table: why this renderer could not draw here
        return {"renderer": renderer, "cloud": cloud, "error": f"{type(exc).__name__}: {exc}"}
    return {"renderer": renderer, "cloud": cloud, "points": len(data["points"]), "base_mb": base,
            "peak_mb": _memory_mb("VmHWM"), "path": str(path), **result}


def _requirements(name: str) -> list[str]:
    """The distributions ``name`` requires (no extras), as normalised names."""
    import importlib.metadata as md

    from packaging.requirements import Requirement

    names = []
    for text in md.requires(name) or []:
        requirement = Requirement(text)
        if requirement.marker is None or requirement.marker.evaluate({"extra": ""}):
            names.append(requirement.name.lower().replace("_", "-"))
    return names


def closure(names) -> set[str]:
    """The installed distributions ``names`` need, themselves included."""
    import importlib.metadata as md

    seen, todo = set(), [n.lower().replace("_", "-") for n in names]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        try:
            md.distribution(name)
        except md.PackageNotFoundError:
            continue
        seen.add(name)
        todo.extend(_requirements(name))
    return seen


def installed_mb(names) -> float:
    """Size of the files pip installed for these distributions (their RECORD), MB."""
    import importlib.metadata as md

    total = 0
    for name in names:
        for file in md.distribution(name).files or []:
            try:
                total += os.path.getsize(file.locate())
            except OSError:
                pass
    return total / 1e6


def install_weight() -> dict:
    """Install sizes: what matplotlib adds to heatcurv's other dependencies; what PyVista adds to all of them."""
    dependencies = _requirements("heatcurv")
    core = closure(dependencies)
    plotting = closure(["matplotlib"]) - closure([name for name in dependencies if name != "matplotlib"])
    weight = {"matplotlib": (installed_mb(plotting), sorted(plotting))}
    extra = closure(["pyvista"]) - core
    weight["pyvista"] = (installed_mb(extra), sorted(extra)) if extra else (float("nan"), ["not installed"])
    return weight


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000, help="points of the torus (default 1000000)")
    parser.add_argument("--out", type=Path, default=Path("/tmp/heatcurv_pictures"), help="folder of the pictures")
    parser.add_argument("--repeat", type=int, default=3,
                        help="runs of each measurement; the fastest is shown (default 3: the machine is shared)")
    parser.add_argument("--one", nargs=2, metavar=("RENDERER", "CLOUD"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.one:
        print(json.dumps(one(args.one[0], args.one[1], args.points, args.out)))
        return

    rows = []
    for cloud in ("torus", "torus200k", "bunny"):
        for renderer in RENDERERS:
            runs = []
            for _ in range(args.repeat):
                command = [sys.executable, __file__, "--one", renderer, cloud, "--points", str(args.points),
                           "--out", str(args.out)]
                done = subprocess.run(command, capture_output=True, text=True, timeout=1800)
                lines = done.stdout.strip().splitlines()
                runs.append(json.loads(lines[-1]) if done.returncode == 0 and lines else {
                    "renderer": renderer, "cloud": cloud, "error": (done.stderr.strip().splitlines() or ["?"])[-1]})
                print(f"  {cloud} {renderer}: {runs[-1].get('draw_s', runs[-1].get('error'))}", file=sys.stderr,
                      flush=True)
            timed = [run for run in runs if "error" not in run]
            row = min(timed, key=lambda run: run["draw_s"]) if timed else runs[-1]  # the least disturbed run
            rows.append(row)

    names = {"torus": f"torus, {args.points:,} points", "torus200k": "torus, 200,000 of them (the default subset)",
             "bunny": "bunny scan, 1839 points"}
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.1f}; python {platform.python_version()}; fastest of {args.repeat} run(s) each")
    print()
    print("| cloud | renderer | import s | draw and save s | peak memory MB | above the loaded cloud MB |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for row in rows:
        if "error" in row:
            print(f"| {names[row['cloud']]} | {row['renderer']} | could not draw: {row['error']} | | | |")
            continue
        print(f"| {names[row['cloud']]} | {row['renderer']} | {row['import_s']:.2f} | {row['draw_s']:.1f} | "
              f"{row['peak_mb']:.0f} | {row['peak_mb'] - row['base_mb']:.0f} |")
    windows = {row["window"] for row in rows if "window" in row}
    if windows:
        print(f"\nPyVista's off-screen window: {', '.join(sorted(windows))}")
    print()
    print("| renderer | installed MB | packages |")
    print("| --- | ---: | --- |")
    weight = install_weight()
    print(f"| matplotlib (added to heatcurv's other dependencies) | {weight['matplotlib'][0]:.0f} | "
          f"{', '.join(weight['matplotlib'][1])} |")
    print(f"| PyVista (added to heatcurv's dependencies) | {weight['pyvista'][0]:.0f} | "
          f"{', '.join(weight['pyvista'][1])} |")
    print(f"\npictures: {args.out}/{{torus,torus200k,bunny}}_{{{','.join(RENDERERS)}}}.png")


if __name__ == "__main__":
    main()
