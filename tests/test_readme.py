"""Numbers README.md states that no module's own tests hold.

The accuracy table is the output of ``heatcurv demo`` (the paper's torus, 20 000 random points, seed 0).
Its ``default`` row is recomputed here and must equal each printed value to the printed digits, read
from README.md itself, so the README cannot go stale when the estimator changes. The ``paper`` row
takes 20-60 s on 2 cores and is not recomputed: the README names the commit and machine of the run
that printed it.
"""

import re
from pathlib import Path

import numpy as np

import heatcurv
from heatcurv.surfaces.accuracy import compare

README = Path(__file__).resolve().parents[1] / "README.md"
COLUMNS = ("mean", "k1", "k2", "Gaussian", "total area", "d1", "normal")


def _readme_row(method):
    """The printed values of ``method``'s row of the accuracy table, as strings, by column name."""
    lines = README.read_text(encoding="utf-8").splitlines()
    header = next(i for i, line in enumerate(lines) if re.match(r"^\| method\s+\| mean", line))
    names = [c.strip() for c in lines[header].strip("|").split("|")]
    assert tuple(names[1:]) == COLUMNS, names
    for line in lines[header + 2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        if cells[0] == method:
            return dict(zip(names[1:], cells[1:]))
    raise AssertionError(f"no {method!r} row under the README's accuracy table")


def test_readme_demo_table_default_row_is_what_the_code_gives():
    printed = _readme_row("default")
    sample = heatcurv.surfaces.get("torus").sample(20000, "random", noise=0.0, seed=0)
    e = compare(sample, heatcurv.estimate(sample.points))
    measured = {"mean": 100 * e["rel_mean"], "k1": 100 * e["rel_k1"], "k2": 100 * e["rel_k2"],
                "Gaussian": 100 * e["rel_gaussian"], "total area": 100 * e["area"], "d1": e["d1_deg"],
                "normal": e["normal_deg"]}
    for name in COLUMNS:
        digits = len(printed[name].split(".")[1]) if "." in printed[name] else 0
        # the printed value is the measured one rounded to its digits (half a last digit, plus rounding)
        assert abs(measured[name] - float(printed[name])) <= 0.5 * 10.0**-digits + 1e-12, (name, measured[name])


def test_eq_2_6_measures_about_half_the_spacing_of_a_random_cloud():
    # README: "eq 2.6 measures about half the spacing sqrt(area / n) of a random cloud" (measured 0.50 at
    # 20 000 random points of the unit sphere, 0.96 on a Fibonacci sphere, whose points are evenly spaced)
    from heatcurv.spacing import global_spacing

    step = np.sqrt(4 * np.pi / 20000)
    random = global_spacing(heatcurv.surfaces.Sphere().sample(20000, "random", seed=1).points) / step
    regular = global_spacing(heatcurv.surfaces.Sphere().sample(20000, "fibonacci").points) / step
    assert 0.45 < random < 0.55 and 0.9 < regular < 1.0
