"""The deprecated modules heatcurv.evaluation and heatcurv.baseline still work, and warn.

A module runs its body once per process, so the in-process test imports it
afresh with :func:`importlib.reload`; the subprocess test checks what a user
script sees: the warning attributed to the script's own import line.
"""

import importlib
import subprocess
import sys

import pytest

import heatcurv.testing

SHIMS = {
    "heatcurv.evaluation": ["aligned_exact", "compare", "direction_error_deg", "paper_error", "relative_l1"],
    "heatcurv.baseline": ["QuadricOptions", "QuadricResult", "quadric_curvature", "RCOND_MIN"],
}


def fresh_import(name):
    if name in sys.modules:
        return importlib.reload(sys.modules[name])
    return importlib.import_module(name)


@pytest.mark.parametrize("name", sorted(SHIMS))
def test_shim_warns_and_reexports(name):
    with pytest.warns(DeprecationWarning, match=rf"{name} is deprecated; use heatcurv\.testing"):
        module = fresh_import(name)
    for attr in SHIMS[name]:
        assert getattr(module, attr) is getattr(heatcurv.testing, attr), attr
    assert set(module.__all__) <= set(SHIMS[name])


def test_old_script_runs_and_sees_the_warning_at_its_import_line():
    script = (
        "from heatcurv import surfaces\n"
        "from heatcurv.evaluation import compare\n"
        "from heatcurv.baseline import quadric_curvature\n"
        "s = surfaces.Sphere().sample(500, 'fibonacci')\n"
        "print(round(compare(s, quadric_curvature(s.points))['orientation'], 3))\n"
    )
    out = subprocess.run(
        [sys.executable, "-W", "always::DeprecationWarning", "-c", script],
        capture_output=True, text=True, check=True,
    )
    assert out.stdout.strip() == "1.0"
    assert "<string>:2: DeprecationWarning: heatcurv.evaluation is deprecated; use heatcurv.testing" in out.stderr
    assert "<string>:3: DeprecationWarning: heatcurv.baseline is deprecated; use heatcurv.testing" in out.stderr
