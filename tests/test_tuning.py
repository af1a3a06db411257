"""The thresholds of the default estimator live in one frozen object, each with a one-line reason."""

import ast
import dataclasses
import re
from pathlib import Path

import pytest

import heatcurv
from heatcurv import tuning
from heatcurv.surfaces import Torus
from heatcurv.tuning import TUNING, Tuning, reasons

SRC = Path(heatcurv.__file__).parent
#: The page whose "## Thresholds" section holds what was measured when each value was set.
HOW_IT_WORKS = Path(__file__).parent.parent / "docs" / "how_it_works.md"

#: The stages that pick a fit path or flag a point.
DECISION_MODULES = (
    "choice/scale", "choice/plan", "fits/anchors", "fits/chordfit", "estimator", "orient/orientation",
    "orient/enclosure", "flags/reliability", "flags/sheets", "flags/outliers", "flags/border", "choice/kernel_check",
    "operators/areas",
)
#: Float literals these stages may still compare against, by source line: geometry and numerics, no choice of path
#: or flag (a quadrature's range, a solver's tolerance, where a winding-number query sits and where its disc ends).
GEOMETRY = {
    ("enclosure", "QUERY_OFFSET = ..."),
    ("enclosure", "ACROSS = ..."),
    ("areas", "keep = x[order] > -0.95"),
    ("areas", "converged = residual <= max(rtol, 1e-12) * 10"),
    ("enclosure", "flat = height <= np.maximum(0.5 * dist, scatter[:, None])"),
    ("enclosure", 'in_plane = flat & (np.einsum("ijk,ik->ij", nrm[idx], nrm) >= 0.5)'),
}


def test_every_threshold_has_a_one_line_reason():
    said = reasons()
    assert set(said) == {f.name for f in dataclasses.fields(Tuning)} and len(said) >= 60
    for name, reason in said.items():
        assert reason and "\n" not in reason and len(reason) <= 120, name


def test_every_threshold_is_in_the_thresholds_table():
    """Each field of :class:`Tuning` is named in docs/how_it_works.md's thresholds section (what was measured).

    The name must stand as a word of its own (``TUNING.noise_levels`` or ``noise_levels``): ``low_noise_levels``
    does not name ``noise_levels``.
    """
    text = HOW_IT_WORKS.read_text(encoding="utf-8")
    assert "\n## Thresholds\n" in text
    section = text.split("\n## Thresholds\n", 1)[1].split("\n## ", 1)[0]
    missing = [f.name for f in dataclasses.fields(Tuning) if not re.search(rf"(?<!\w){f.name}(?!\w)", section)]
    assert not missing, f"fields of Tuning not in docs/how_it_works.md, section Thresholds: {missing}"


def test_the_thresholds_are_frozen_and_a_study_replaces_them():
    with pytest.raises(dataclasses.FrozenInstanceError):
        TUNING.strong_noise = 1.0
    study = dataclasses.replace(TUNING, tiny_patch=1)
    assert study.tiny_patch == 1 and TUNING.tiny_patch == 2 and study.strong_noise == TUNING.strong_noise


def _float_literals(node):
    return [c.value for c in ast.walk(node)
            if isinstance(c, ast.Constant) and isinstance(c.value, float) and c.value not in (0.0, 1.0)]


@pytest.mark.parametrize("module", DECISION_MODULES)
def test_no_stage_compares_against_a_number_of_its_own(module):
    """A comparison with a fractional literal in a decision stage is a threshold outside :data:`TUNING`."""
    source = (SRC / f"{module}.py").read_text()
    lines = source.splitlines()
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare) and _float_literals(node):
            found.add((module.rpartition("/")[2], lines[node.lineno - 1].strip()))
        # a module constant holding a fractional number (NAME = 0.3) is a threshold of its own too
        if isinstance(node, ast.Assign) and node.col_offset == 0 and _float_literals(node.value):
            names = [t.id for t in node.targets if isinstance(t, ast.Name)]
            found |= {(module.rpartition("/")[2], f"{name} = ...") for name in names}
    assert found <= GEOMETRY, sorted(found - GEOMETRY)


def test_the_estimator_reads_the_tuning_it_is_given(monkeypatch):
    """The stages read :data:`TUNING` when they run: a study's value changes what the estimator does."""
    points = Torus().sample(3000, "random", seed=3).points
    base = heatcurv.estimate(points)
    for module in ("heatcurv.flags.reliability", "heatcurv.estimator"):
        monkeypatch.setattr(f"{module}.TUNING", dataclasses.replace(TUNING, resolution_limit=1e-3))
    coarse = heatcurv.estimate(points)
    assert base.reliable.mean() > 0.9 and not coarse.reliable.any()
    assert tuning.TUNING.resolution_limit == 0.5
