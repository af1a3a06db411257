"""Calibration of heatcurv's standard errors (``mean_se``, ``k1_se``, ``k2_se``, ``normal_se``) against exact values.

On the clouds of ``benchmarks/accuracy.py`` (its clean clouds at 20 000 points with the three
samplers, its noise table, its very-low-noise band and its held-out clouds, the same seeds and
interior margins), ``heatcurv.estimate(points)`` with default options, judged at the reliable
interior points; and on the scenes of :mod:`heatcurv.surfaces.scenes` (the LiDAR tile, with its
noise and centimetre rounding, ``orient="up"``; the CAD part, clean and noisy), whose mean
curvature and normals are exact where defined (not in the trees, not near a sharp edge):

* coverage: the share of points whose true error is within two standard errors
  (``|value - exact| <= 2 se``; the normal: the angle to the exact normal), %;
  independent Gaussian errors with exact standard errors give 95.4 % (the normal's angle,
  a 2-D error: 98.2 %);
* sharpness: the median standard error over the median absolute error (exact
  Gaussian standard errors: 1.48; above 2.5 the bars are too wide to be useful).

The verdict of a cloud is ``ok`` when the coverage of mean, k1 and k2 lies within 90-98 % and
their sharpness is at most 2.5 (issue 30), else what fails: ``under`` (coverage below 90 %),
``over`` (above 98 %: bars wider than independent Gaussian errors would need, or errors that vary
less than Gaussian ones within a region) or ``wide`` (sharpness above 2.5), with the fields. ``t`` is the whole
estimate's time and ``se t`` its ``standard_errors`` stage's.

``--picture FILE`` draws the reliability diagram: for every cloud kind (clean, noisy, very low
noise, held out), the share of points whose error is within ``z`` standard errors against
``z``, beside the share independent Gaussian errors would give.

Run:  python benchmarks/error_bars.py [--markdown FILE] [--picture FILE] [--tables clean,noise,lownoise,heldout]
      python benchmarks/error_bars.py --scans-picture docs/error_bars_scans.png   (where the bars are wide on scans:
      the bunny scan, a face range map, a CAD part, a LiDAR tile)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np
from scipy.special import erf

import heatcurv
from heatcurv.surfaces.accuracy import aligned_exact, neighbour_margin

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import accuracy as acc  # noqa: E402  (benchmarks/accuracy.py: its clouds, seeds and margins)
from machine import commit, cpu_model, memory_text  # noqa: E402

#: The fields judged, with the result's standard error of each.
FIELDS = ("mean", "k1", "k2", "normal")
#: Coverage band and widest sharpness of the verdict.
COVERAGE = (90.0, 98.0)
SHARPNESS = 2.5
#: Multiples of the standard error of the reliability diagram.
Z = np.linspace(0.0, 4.0, 81)


def clouds(tables):
    """(table, label, sample factory, margin rule) of every cloud of the chosen tables."""
    if "clean" in tables:
        for surface in ("sphere", "ellipsoid", "torus", "paraboloid", "saddle", "cylinder"):
            for sampler in ("random", "jittered", "scan"):
                yield "clean", f"{surface} {sampler} 20000", \
                    lambda s=surface, m=sampler: acc.make_sample(s, m, 20000)[0]
    if "noise" in tables:
        extra = [(s, acc.NOISE_N) for s in ("sphere", "ellipsoid", "torus", "paraboloid", "saddle", "cylinder")]
        for surface, n in extra + list(acc.NOISE_EXTRA):
            for noise in acc.NOISES:
                yield "noise", f"{surface} {n} noise {100 * noise:g} %", \
                    lambda s=surface, n=n, z=noise: acc.make_sample(s, "random", n, z)[0]
    if "lownoise" in tables:
        for surface in acc.LOWNOISE_SURFACES:
            seed = acc.seed_of(surface, "lownoise", acc.LOWNOISE_N)
            for noise in acc.LOWNOISES[1:]:
                yield "lownoise", f"{surface} {acc.LOWNOISE_N} noise {noise:g}", \
                    lambda s=surface, z=noise, seed=seed: acc.make_surface(s).sample(acc.LOWNOISE_N, "random", noise=z,
                                                                                      seed=seed)
    if "scenes" in tables:
        from heatcurv import surfaces as hs

        yield "scenes", "lidar_tile(20000) noise 0.03 m", lambda: hs.lidar_tile(20000, seed=0)
        yield "scenes", "cad_part(20000)", lambda: hs.cad_part(20000)
        yield "scenes", "cad_part(20000) noise 0.05 mm", lambda: hs.cad_part(20000, noise=0.05)
    if "heldout" in tables:
        for name, params, sampler, n, noise, seed in acc.HELDOUT:
            yield "heldout", f"{acc.heldout_label(name, params)} {sampler} {n} noise {100 * noise:g} %", \
                lambda name=name, params=params, sampler=sampler, n=n, noise=noise, seed=seed: \
                acc.heldout_surface(name, params).sample(n, sampler, noise=noise, seed=seed)


def margin_of(table: str, sample) -> float:
    """The interior margin ``benchmarks/accuracy.py`` judges the cloud with."""
    if table == "clean":
        return 0.0 if sample.surface.closed else neighbour_margin(sample.clean_points)
    if table == "heldout":
        return acc.heldout_margin(sample)
    return acc.eval_margin(sample)


def ratios(sample, res, margin: float) -> dict:
    """Each field's ``|error| / se`` at the reliable interior points."""
    exact = aligned_exact(sample, res)
    inner = sample.interior(margin) & res.reliable
    out = {}
    with np.errstate(divide="ignore", invalid="ignore"):
        for name in FIELDS[:3]:
            error = np.abs(getattr(res, name) - exact[name])[inner]
            out[name] = (error, getattr(res, name + "_se")[inner])
        cosine = np.clip(np.abs(np.einsum("ij,ij->i", res.normals, exact["normals"])), 0.0, 1.0)
        out["normal"] = (np.degrees(np.arccos(cosine))[inner], res.normal_se[inner])
    return out


def scene_ratios(scene, res) -> dict:
    """A scene's (:mod:`heatcurv.surfaces.scenes`) ``|error|`` and ``se`` of the mean curvature and the normal, at
    the reliable points where its curvature is defined (not in vegetation, not near a sharp edge)."""
    side = np.sign(np.einsum("ij,ij->i", res.normals, scene.normals))  # the exact values for the normal's side
    inner = res.reliable & np.isfinite(scene.mean)
    cosine = np.clip(np.abs(np.einsum("ij,ij->i", res.normals, scene.normals)), 0.0, 1.0)
    return {"mean": (np.abs(res.mean - side * scene.mean)[inner], res.mean_se[inner]),
            "normal": (np.degrees(np.arccos(cosine))[inner], res.normal_se[inner])}


def verdict(scores: dict) -> str:
    """``ok``, or what fails among mean, k1 and k2: ``under`` (coverage below the band), ``over`` (above it),
    ``wide`` (sharpness above :data:`SHARPNESS`), each with its fields."""
    parts = []
    for word, test in (("under", lambda c, s: c < COVERAGE[0]), ("over", lambda c, s: c > COVERAGE[1]),
                       ("wide", lambda c, s: s > SHARPNESS)):
        names = [name for name in FIELDS[:3] if name in scores and test(*scores[name])]
        if names:
            parts.append(f"{word} {' '.join(names)}")
    return "; ".join(parts) or "ok"


def _ratio(value: float) -> str:
    """A sharpness: two decimals, or two digits where exact values made the median error ~0 (a flat face)."""
    return f"{value:.2f}" if value < 1000 else f"{value:.2g}"


def run(tables, log):
    rows, pooled = [], {}
    for table, label, make in clouds(tables):
        sample = make()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            start = time.perf_counter()
            # the LiDAR tile as the command line reads a LAS file: normals up
            res = heatcurv.estimate(sample.points, **({"orient": "up"} if "lidar" in label else {}))
            seconds = time.perf_counter() - start
        if table == "scenes":
            measured = scene_ratios(sample, res)
        else:
            measured = ratios(sample, res, margin_of(table, sample))
        scores = {}
        for name, (error, se) in measured.items():
            scores[name] = (100 * float(np.mean(error <= 2 * se)), float(np.median(se) / np.median(error)))
            share = np.mean(error[:, None] <= Z[None, :] * se[:, None], axis=0)
            pooled.setdefault((table, name), []).append(share)
        plan = res.info["plan"]
        rows.append([table, label, plan.label,
                     *(f"{scores[n][0]:.1f}" if n in scores else "-" for n in FIELDS),
                     *(_ratio(scores[n][1]) if n in scores else "-" for n in FIELDS), f"{seconds:.1f}",
                     f"{res.info['timings'].get('standard_errors', float('nan')):.2f}", verdict(scores)])
        log(" | ".join(rows[-1]))
    return rows, pooled


def picture(pooled: dict, path: str) -> None:
    """The reliability diagram: share within z standard errors against z, per cloud kind, for mean, k1, k2."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(16, 4.2), sharey=True)
    gaussian = erf(Z / np.sqrt(2))  # |N(0, 1)| <= z
    for ax, name in zip(axes, FIELDS):
        ax.plot(Z, 100 * gaussian if name != "normal" else 100 * (1 - np.exp(-Z**2)), "k--", lw=1,
                label="exact Gaussian errors")
        for table in ("clean", "noise", "lownoise", "heldout", "scenes"):
            shares = pooled.get((table, name))
            if shares:
                ax.plot(Z, 100 * np.mean(shares, axis=0), lw=1.8, label=f"{table} ({len(shares)} clouds)")
        ax.axvline(2.0, color="0.7", lw=0.8)
        ax.set_title(f"{name}_se")
        ax.set_xlabel("z (multiples of the standard error)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("points with |error| <= z se (%)")
    axes[0].legend(loc="lower right", fontsize=8)
    fig.suptitle("heatcurv's standard errors against exact errors (mean over the clouds of each kind)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def real_picture(path: str) -> None:
    """Where the bars are wide on scans: ``log10(mean_se)`` on the shipped bunny scan, pymeshlab's face range map,
    the simulated CAD part and the simulated LiDAR tile (``docs/error_bars_scans.png``)."""
    from heatcurv import surfaces as hs
    from heatcurv.render import FieldStyle

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
    from heatcurv.data import load_bunny
    from real_scans import render_panels
    from support.scans import fetch_pymeshlab_samples, read_mesh

    face = read_mesh(fetch_pymeshlab_samples() / "rangemaps" / "face000.ply").vertices
    cad, lidar = hs.cad_part(20000).points, hs.lidar_tile(20000, seed=0).points
    bunny = np.asarray(load_bunny().points, dtype=np.float64)
    panels = []
    for points, options, unit, view, title in (
        (bunny, {}, "length", {"view": (0, 0, 1), "up": (0, 1, 0)}, "bunny scan (1 839 points)"),
        (face, {}, "mm", {"view": (0, 0, 1), "up": (0, 1, 0)}, "face000 range map (85 849 points)"),
        (cad, {}, "mm", {"view": (0.5, -1.0, 0.0), "up": (0, 0, 1), "elevation": 35.0}, "CAD part (20 000)"),
        (lidar, {"orient": "up"}, "m", {"view": (0, -1, 0), "up": (0, 0, 1), "elevation": 40.0, "vertical": "z"},
         "LiDAR tile (20 000)"),
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = heatcurv.estimate(points, **options)
        with np.errstate(divide="ignore"):
            shown = np.where(np.isfinite(res.mean_se), np.log10(res.mean_se), np.nan)  # outliers: grey
        style = FieldStyle("log10 of the mean curvature's standard error", f"log10(1/{unit})", "sequential")
        panels.append((points, {"values": shown, "field": style, "normals": res.normals, "title": title, **view}))
    import tempfile

    import matplotlib.image

    with tempfile.TemporaryDirectory() as tmp:
        parts = []
        for k, (points, panel) in enumerate(panels):
            part = os.path.join(tmp, f"panel{k}.png")
            title = panel.pop("title")
            render_panels(points, [panel], part, size=(800, 700), title=title)
            parts.append(matplotlib.image.imread(part)[..., :3])
        height = max(p.shape[0] for p in parts)
        parts = [np.pad(p, ((0, height - p.shape[0]), (0, 0), (0, 0)), constant_values=1.0) for p in parts]
        matplotlib.image.imsave(path, np.concatenate(parts, axis=1))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tables", default="clean,noise,lownoise,heldout,scenes")
    parser.add_argument("--markdown", metavar="FILE", help="also write the table to FILE")
    parser.add_argument("--picture", metavar="FILE", help="draw the reliability diagram into FILE (PNG)")
    parser.add_argument("--scans-picture", metavar="FILE",
                        help="only draw mean_se on a face scan, a CAD part and a LiDAR tile into FILE (PNG)")
    args = parser.parse_args(argv)
    if args.scans_picture:
        real_picture(args.scans_picture)
        print(f"picture: {args.scans_picture}")
        return 0
    tables = [t for t in args.tables.split(",") if t]
    start = time.perf_counter()
    head = (f"Machine: {cpu_model()}, {os.cpu_count()} cores{memory_text()}; heatcurv {heatcurv.__version__} at "
            f"commit {commit()}; load average {os.getloadavg()[0]:.1f} at the start")
    print(head, flush=True)
    rows, pooled = run(tables, lambda line: print(line, flush=True))
    header = ["table", "cloud", "fit", *(f"cov {n} %" for n in FIELDS), *(f"sharp {n}" for n in FIELDS), "t s",
              "se t s", "verdict"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    count = {word: sum(word in row[-1] for row in rows) for word in ("ok", "under", "over", "wide")}
    summary = (f"{count['ok']} of {len(rows)} clouds within coverage {COVERAGE[0]:g}-{COVERAGE[1]:g} % and "
               f"sharpness <= {SHARPNESS:g} for mean, k1 and k2; coverage below {COVERAGE[0]:g} % in some of "
               f"them: {count['under']}, above {COVERAGE[1]:g} %: {count['over']}, sharpness above {SHARPNESS:g}: "
               f"{count['wide']}; whole run {time.perf_counter() - start:.0f} s")
    text = "\n".join([head, "", *lines, "", summary])
    print("\n" + text)
    if args.markdown:
        with open(args.markdown, "w") as out:
            out.write(text + "\n")
    if args.picture:
        picture(pooled, args.picture)
        print(f"picture: {args.picture}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
