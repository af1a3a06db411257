"""heatcurv.cli.view: ``heatcurv view`` writes the page of any file the command line reads."""

import webbrowser

import numpy as np
import pytest
from cli_helpers import WRITTEN, assert_one_line_error, run

from heatcurv import io
from heatcurv.cli import view as cli_view
from support.view_page import field, page_block, positions


def test_view_of_a_computed_file_holds_its_fields_normals_and_reliable_mask(sphere_fields_ply, sphere_cloud):
    out, path = sphere_fields_ply
    assert out.returncode == 0, out.stderr
    page = path.with_suffix(".html")
    shown = run("view", path)
    assert shown.returncode == 0, shown.stderr
    lines = shown.stdout.splitlines()
    assert lines[1].startswith(f"wrote {page}: 3000 points, 19 field(s), first mean; ")
    assert lines[2] == f"  open it in a web browser: {page.resolve().as_uri()}"
    block = page_block(page)
    names = [e["name"] for e in block["fields"]]
    assert names == WRITTEN[:3] + ["intensity"] + WRITTEN[3:] + ["x", "y", "z"]
    assert block["field"] == "mean" and block["title"] == path.name and block["notes"] == []
    assert block["normals"] is not None and block["reliable"] is not None
    cloud = io.read_points(path)
    assert np.array_equal(field(block, "mean"), cloud.fields["mean"].astype(np.float32))
    assert np.array_equal(field(block, "intensity"), sphere_cloud[2].astype(np.float32))
    assert np.allclose(positions(block), sphere_cloud[0], rtol=0, atol=1e-6)
    greyed = {e["name"] for e in block["fields"] if e["grey"]}
    assert greyed == set(WRITTEN) - {"reliable"}


def test_view_of_a_raw_cloud_in_another_format(tmp_path, sphere_cloud):
    points = sphere_cloud[0]
    io.write_points(tmp_path / "cloud.xyz", points)
    out = run("view", tmp_path / "cloud.xyz", "-o", tmp_path / "raw.htm", "--max-points", "500", "--title", "raw")
    assert out.returncode == 0, out.stderr
    assert "wrote" in out.stdout and "a random 500 of 3000 points" in out.stdout
    assert "--max-points N shows more" in out.stdout and "holds no curvature" in out.stdout
    block = page_block(tmp_path / "raw.htm")
    assert [e["name"] for e in block["fields"]] == ["x", "y", "z"] and block["field"] == "y"
    assert block["count"] == 500 and block["title"] == "raw" and block["normals"] is None
    assert block["notes"][0] == "Showing a random 500 of the 3,000 points."
    assert "heatcurv compute cloud.xyz" in block["notes"][1]


def test_fields_option_keeps_the_page_small(sphere_fields_ply, tmp_path):
    _, path = sphere_fields_ply
    out = run("view", path, "-o", tmp_path / "small.html", "--fields", "k1,k2,reliable", "--field", "k2", "-q")
    assert out.returncode == 0 and out.stdout == "", out.stderr
    block = page_block(tmp_path / "small.html")
    assert [e["name"] for e in block["fields"]] == ["k1", "k2", "reliable", "x", "y", "z"]
    assert block["field"] == "k2"
    full = run("view", path, "-o", tmp_path / "full.html", "-q")
    assert full.returncode == 0
    assert (tmp_path / "small.html").stat().st_size < 0.5 * (tmp_path / "full.html").stat().st_size


@pytest.mark.parametrize("extra, message", [
    (["--field", "temperature"], "--field: {input} has no field 'temperature'; it holds nx, ny, nz, intensity"),
    (["--fields", "mean,k9"], "--fields: {input} has no field 'k9'"),
    (["--fields", "mean", "--field", "k1"], "--field 'k1' is not among --fields mean"),
    (["-o", "{dir}/view.png"], "unknown page extension '.png'; supported: .html .htm"),
    (["-o", "{dir}/no/view.html"], "does not exist"),
    (["--max-points", "0"], "max_points = 0 is outside its range"),
])
def test_view_errors_are_one_line(sphere_fields_ply, tmp_path, extra, message):
    _, path = sphere_fields_ply
    args = [a.format(dir=tmp_path) for a in extra]
    out = run("view", path, *(args if "-o" in args else ["-o", tmp_path / "view.html", *args]))
    assert_one_line_error(out)
    assert message.format(input=path) in out.stderr
    assert list(tmp_path.iterdir()) == []


def test_missing_empty_and_pointless_files(tmp_path):
    out = run("view", tmp_path / "nothere.ply")
    assert_one_line_error(out)
    assert "no such file" in out.stderr
    (tmp_path / "empty.xyz").write_text("")
    assert "the file is empty" in run("view", tmp_path / "empty.xyz").stderr
    (tmp_path / "nan.xyz").write_text("nan 0 0\n0 nan 0\n")
    out = run("view", tmp_path / "nan.xyz")
    assert_one_line_error(out)
    assert "none of the 2 points has finite coordinates: nothing to show" in out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.xyz", "nan.xyz"]


class _Desktop(webbrowser.BackgroundBrowser):
    """A desktop browser that notes what it is asked to open instead of starting."""

    def __init__(self):
        super().__init__(["firefox"])
        self.opened = []

    def open(self, url, new=0, autoraise=True):
        self.opened.append(url)
        return True


def test_a_browser_opens_only_on_a_desktop_and_never_a_text_one(monkeypatch, tmp_path):
    page = tmp_path / "view.html"
    browser = _Desktop()
    monkeypatch.setattr(webbrowser, "get", lambda: browser)
    monkeypatch.setattr(cli_view.sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert cli_view.open_in_browser(page) is False and browser.opened == []
    monkeypatch.setenv("DISPLAY", ":0")
    assert cli_view.open_in_browser(page) is True and browser.opened == [page.resolve().as_uri()]
    monkeypatch.setattr(webbrowser, "get", lambda: webbrowser.GenericBrowser("lynx"))
    assert cli_view.open_in_browser(page) is False
