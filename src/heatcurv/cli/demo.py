"""``heatcurv demo``: the estimator on a built-in example, an analytic surface or the Stanford bunny scan."""

from __future__ import annotations

import textwrap
import time
import warnings

import numpy as np

from .. import __version__, surfaces
from ..errors import HeatcurvWarning
from .console import EXIT_OK, Log
from .steps import check_output_path, run_estimate

__all__ = ["run"]

#: Width the demo's sentences are wrapped to (the error table is 91 characters wide).
WIDTH = 96


def run(args, log: Log) -> int:
    """Run ``heatcurv demo`` on the parsed arguments."""
    picture = None
    if not args.no_picture:
        from ..render import supported_picture_formats

        default = "heatcurv_bunny.png" if args.bunny else "heatcurv_demo.png"
        picture = check_output_path(args.output or default, supported_picture_formats(), "picture")
    if args.bunny:
        return _demo_bunny(picture, log)
    return _demo_surface(args, picture, log)


def _demo_surface(args, picture, log: Log) -> int:
    """Both methods on a sample of an analytic surface: the error table, and a picture of the mean curvature.

    The paper's method warns on the samples it is not made for (random, scan-like, noisy): the demo
    keeps those warnings for ``--verbose`` and says in one sentence what they mean.
    """
    from ..estimator import estimate
    from ..surfaces.accuracy import compare

    surface = surfaces.get(args.surface)
    sample = surface.sample(args.n, args.sampler, noise=args.noise, seed=args.seed)
    noise = "no noise" if args.noise == 0 else f"noise {args.noise:g} of the bounding-box diagonal"
    print(f"heatcurv {__version__} demo: {surface.name}, {len(sample.points)} points ({args.sampler} sampler, {noise})")
    print("methods: default (built for irregular, scanned and noisy clouds) and paper (the paper's, literally)")
    rows = []
    for method in ("default", "paper"):
        tic = time.perf_counter()
        if method == "paper":
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", HeatcurvWarning)
                res = estimate(sample.points, method=method)
            paper_warnings = [w for w in caught if issubclass(w.category, HeatcurvWarning)]
        else:
            res = estimate(sample.points, method=method)  # its warnings, if any, are the command's
        seconds = time.perf_counter() - tic
        rows.append((method, compare(sample, res), seconds, res.info.get("scale"), res))
    _print_error_table(rows)
    scale = rows[0][3]
    print(f"the default's kernel here: {scale.fit}, noise estimate {scale.sigma:.2g}.")
    if paper_warnings:
        what = "noisy" if args.noise > 0 else args.sampler
        print(textwrap.fill(
            f"The paper's method is made for regular, clean samples and warned about this {what} one: its errors "
            "above are the method's, not a fault (--verbose prints its warnings; --surface sphere --sampler "
            "fibonacci gives it a regular sample).", width=WIDTH,
        ))
        for w in paper_warnings:
            log.detail(f"the paper's method warned: {' '.join(str(w.message).split())}")
    if picture is not None:
        from ..render import grey_unreliable, render_field

        res = rows[0][4]
        render_field(
            sample.points, grey_unreliable(res.mean, res.reliable), picture, field="mean", size=(1400, 1000),
            normals=res.normals, elevation=35.0 if surface.name == "torus" else 0.0,
            title=f"heatcurv demo: mean curvature of the {surface.name}, {len(sample.points)} {args.sampler} points",
        )
        print(f"\nwrote {picture}: the mean curvature (default method){_grey_note(res.reliable)}")
    return EXIT_OK


def _grey_note(reliable: np.ndarray) -> str:
    """``"; grey: the N unreliable points"``, or ``""`` if every point is reliable."""
    unreliable = int(np.count_nonzero(~np.asarray(reliable, dtype=bool)))
    return f"; grey: the {unreliable} unreliable point(s)" if unreliable else ""


def _print_error_table(rows) -> None:
    """The errors of each method, rows ``(method, errors, seconds, scale report, result)``, and what they mean."""

    def pct(x):
        return "       -" if x != x else f"{100 * x:8.3f}"  # NaN: exact field is zero

    print()
    print("relative L1 error (%) on interior points; angles in degrees")
    print(
        f"{'method':8s} {'mean':>8s} {'k1':>8s} {'k2':>8s} {'gauss':>8s} {'area':>8s} {'d1':>7s} "
        f"{'normal':>7s} {'orient':>7s} {'time s':>7s}"
    )
    for method, e, seconds, _, _ in rows:
        print(
            f"{method:8s} {pct(e['rel_mean'])} {pct(e['rel_k1'])} {pct(e['rel_k2'])} {pct(e['rel_gaussian'])} "
            f"{100 * e['area']:+8.3f} {e['d1_deg']:7.3f} {e['normal_deg']:7.3f} {100 * e['orientation']:6.2f}% "
            f"{seconds:7.2f}"
        )
    print()
    print("area: relative error of the total (open surfaces: biased by the border).")


def _demo_bunny(picture, log: Log) -> int:
    """The default method on the Stanford bunny scan: timing, field percentiles, a front-and-back picture."""
    from ..data import BUNNY_ATTRIBUTION, bunny_path
    from ..io import read_points

    path = bunny_path()
    cloud = read_points(path)
    print(f"heatcurv {__version__} demo: a real scan, {len(cloud)} points ({path.name}, shipped with heatcurv)")
    print(f"  {BUNNY_ATTRIBUTION}")
    res = run_estimate(cloud.points, None, {"method": "default"}, Log(quiet=True))
    seconds = sum(res.info["timings"].values())
    scale = res.info["scale"]
    print(
        f"\ncomputed in {seconds:.2f} s: kernel {scale.fit} ({scale.k} neighbours), "
        f"noise estimate {scale.sigma:.2g} ({scale.relative_noise:.2g} of "
        f"the spacing); {int(res.reliable.sum())} of {len(res)} points reliable"
    )
    print(f"\n{'field':10s} {'2 %':>9s} {'median':>9s} {'98 %':>9s}  unit")
    units = (("mean", "1/length"), ("gaussian", "1/length^2"), ("k1", "1/length"), ("k2", "1/length"),
             ("area", "length^2"))
    for name, unit in units:
        low, mid, high = np.percentile(getattr(res, name)[res.reliable], [2, 50, 98])
        print(f"{name:10s} {low:9.3g} {mid:9.3g} {high:9.3g}  {unit}")
    print(f"total area {res.area.sum():.4g} length^2 (the scan has holes and a cut base)")
    if picture is not None:
        from ..render import grey_unreliable, render_field

        render_field(
            cloud.points, grey_unreliable(res.mean, res.reliable), picture, field="mean", views=2, size=(1600, 800),
            normals=res.normals,
            title=f"heatcurv demo: mean curvature of the Stanford bunny scan ({len(cloud)} points)",
        )
        print(f"\nwrote {picture}: the mean curvature, front and back{_grey_note(res.reliable)}")
    print("\nthe same from the command line:")
    print(f"  heatcurv compute {path} -o bunny_curvature.ply")
    print("  heatcurv render bunny_curvature.ply -o bunny_mean.png --field mean --views 2")
    return EXIT_OK
