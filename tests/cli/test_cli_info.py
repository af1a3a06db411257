"""heatcurv.cli.info: ``heatcurv info`` describes a file."""

import re

from cli_helpers import run

from heatcurv.data import bunny_path


def test_info_on_the_bunny_and_on_computed_fields(workdir, sphere_ply):
    out = run("info", bunny_path())
    assert out.returncode == 0, out.stderr
    assert re.search(r"^points\s+1839 \(1839 distinct\)$", out.stdout, flags=re.MULTILINE), out.stdout
    assert "PLY (ascii)" in out.stdout and "normals      no" in out.stdout
    assert re.search(r"median distance to the nearest neighbour 0\.28\d+", out.stdout)
    out = run("info", sphere_ply)
    assert re.search(r"^points\s+3000 ", out.stdout, flags=re.MULTILINE)
    assert "colours      yes" in out.stdout and "intensity" in out.stdout
    assert re.search(r"x\s+-0\.99\d+ \.\. 0\.99\d+", out.stdout)


def test_info_reports_nonfinite_rows(tmp_path):
    path = tmp_path / "nan.xyz"
    path.write_text("0 0 0\n1 0 0\nnan 1 1\n0 1 0\n1 1 1\n")
    out = run("info", path)
    assert out.returncode == 0, out.stderr
    assert "points       5 (4 distinct)" in out.stdout
    assert "non-finite   1 row(s)" in out.stdout
