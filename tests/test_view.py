"""heatcurv.view: the page is self-contained and embeds exactly the points and fields given."""

import re

import numpy as np
import pytest

from heatcurv import HeatcurvError, surfaces
from heatcurv.render import colour_limits
from heatcurv.view import write_view
from support.view_page import DATA_BLOCK as DATA_BLOCK_TEXT
from support.view_page import byte_array, field, floats, page_block, positions


@pytest.fixture(scope="module")
def cloud():
    """2000 random points on a sphere, outward normals, a signed and a positive field, a reliable mask."""
    points = surfaces.Sphere(radius=2.0).sample(2000, "random", seed=1).points
    rng = np.random.default_rng(2)
    fields = {"mean": 0.5 + 0.1 * rng.standard_normal(2000), "area": rng.uniform(1e-3, 2e-3, 2000),
              "reliable": (rng.uniform(size=2000) > 0.1)}
    return points, fields


def test_the_page_fetches_nothing_and_says_so_to_the_browser(tmp_path, cloud):
    points, fields = cloud
    path = tmp_path / "view.html"
    write_view(points, fields, path, points)
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    assert not re.search(r"https?://", text)
    assert not re.search(r"<(link|img|iframe|object|embed)\b", text, re.I)
    assert not re.search(r"\b(src|href)\s*=", text, re.I)
    assert not re.search(r"\b(fetch|XMLHttpRequest|importScripts|import)\s*\(", text)
    assert "content=\"default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data:\"" \
        in text
    assert text.count("<script") == 2 and text.count("</script>") == 2  # the data block and the renderer


def test_the_page_embeds_every_point_and_field_as_given(tmp_path, cloud):
    points, fields = cloud
    view = write_view(points, fields, tmp_path / "view.html", points, reliable=fields["reliable"])
    block = page_block(view.path)
    assert view.shown == view.total == block["count"] == block["total"] == 2000
    assert view.fields == ("mean", "area", "reliable", "x", "y", "z") and view.field == "mean"
    assert [e["name"] for e in block["fields"]] == list(view.fields)
    # float32 offsets from the centre, the centre in float64: the points to float32 precision
    centre = np.asarray(block["centre"])
    assert np.array_equal(floats(block["positions"]).reshape(-1, 3), (points - centre).astype(np.float32))
    assert np.allclose(positions(block), points, rtol=0, atol=4e-7)
    for name, values in fields.items():
        assert np.array_equal(field(block, name), np.asarray(values, dtype=np.float32)), name
    assert np.array_equal(field(block, "z"), positions(block)[:, 2])
    # normals as int8 unit vectors, the mask as bytes
    normals = byte_array(block["normals"], "i1").reshape(-1, 3) / 127.0
    assert np.abs(normals - points / 2.0).max() < 0.01
    assert np.array_equal(byte_array(block["reliable"], "u1"), fields["reliable"].astype(np.uint8))
    assert view.size == view.path.stat().st_size


def test_colour_limits_are_the_pictures_and_leave_out_unreliable_points(tmp_path, cloud):
    points, fields = cloud
    reliable = fields["reliable"]
    view = write_view(points, fields, tmp_path / "view.html", reliable=reliable)
    block = page_block(view.path)
    entries = {e["name"]: e for e in block["fields"]}
    for name in ("mean", "area"):
        low, high, kind = colour_limits(np.where(reliable, fields[name], np.nan),
                                        "signed" if name == "mean" else "sequential")
        assert view.limits[name] == (low, high, kind)
        assert (entries[name]["low"], entries[name]["high"], entries[name]["kind"]) == (low, high, kind)
        assert entries[name]["grey"] is True
    assert view.limits["reliable"] == (-0.5, 1.5, "mask") and entries["reliable"]["grey"] is False
    # the mean curvature here is positive everywhere: the sequential map over its own range, as in the pictures
    low, high, kind = view.limits["mean"]
    assert kind == "sequential" and 0.25 < low < 0.5 < high < 0.75
    # the robust limits lie inside the values' range
    area = fields["area"][reliable]
    assert area.min() < view.limits["area"][0] < view.limits["area"][1] < area.max()


def test_a_large_cloud_is_thinned_with_a_seed_and_the_page_says_so(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.uniform(-1, 1, (5000, 3))
    points[:10] = np.nan
    fields = {"height": points[:, 2] * 10}
    one = write_view(points, fields, tmp_path / "a.html", max_points=800)
    two = write_view(points, fields, tmp_path / "b.html", max_points=800)
    other = write_view(points, fields, tmp_path / "c.html", max_points=800, seed=1)
    block = page_block(one.path)
    assert one.shown == block["count"] == 800 and one.total == 5000
    assert block["notes"] == ["Showing a random 800 of the 4,990 points.",
                              "10 point(s) without finite coordinates are not shown."]
    shown = positions(block)
    # a subset of the input rows, each with its own value
    distance = np.linalg.norm(shown[:, None, :] - points[None, 10:, :], axis=2)
    rows = 10 + np.nanargmin(distance, axis=1)
    assert np.nanmin(distance, axis=1).max() < 1e-6 and np.unique(rows).size == 800
    assert np.array_equal(field(block, "height"), fields["height"][rows].astype(np.float32))
    assert one.path.read_bytes() == two.path.read_bytes()
    assert not np.array_equal(positions(page_block(other.path)), shown)
    everything = write_view(points, fields, tmp_path / "d.html")
    assert everything.shown == 4990 and page_block(everything.path)["notes"] == [
        "10 point(s) without finite coordinates are not shown."]


def test_values_beyond_float32_keep_their_digits(tmp_path):
    points = surfaces.Sphere().sample(300, "fibonacci").points * 1e-30  # a cloud in extreme units
    fields = {"mean": np.full(300, 1e30) * (1 + points[:, 0] * 1e29), "area": np.full(300, 1e-62)}
    view = write_view(points, fields, tmp_path / "tiny.html")
    block = page_block(view.path)
    for name, values in fields.items():
        assert np.allclose(field(block, name), values, rtol=1e-7, atol=0), name
    assert np.allclose(positions(block), points, rtol=0, atol=1e-36)
    assert block["fields"][1]["values"]["exponent"] != 0


def test_names_and_titles_cannot_break_out_of_the_page(tmp_path, cloud):
    points, _ = cloud
    name = "</script><script>alert(1)</script>&amp;"
    view = write_view(points, {name: points[:, 0]}, tmp_path / "view.html", title="<b>bunny</b> & co")
    text = view.path.read_text(encoding="utf-8")
    assert text.count("</script>") == 2 and "alert(1)</script>" not in text
    assert "<title>&lt;b&gt;bunny&lt;/b&gt; &amp; co</title>" in text
    block = page_block(view.path)
    assert block["fields"][0]["name"] == name and block["title"] == "<b>bunny</b> & co"


def test_an_n_by_3_field_gives_three_components_and_a_raw_cloud_its_height(tmp_path, cloud):
    points, _ = cloud
    view = write_view(points, {"d1": points / 2.0}, tmp_path / "view.html")
    assert view.fields == ("d1x", "d1y", "d1z", "x", "y", "z") and view.field == "d1x"
    assert np.array_equal(field(page_block(view.path), "d1y"), (points[:, 1] / 2.0).astype(np.float32))
    raw = write_view(points, {}, tmp_path / "raw.html", vertical="z")
    assert raw.fields == ("x", "y", "z") and raw.field == "z"


@pytest.mark.parametrize("args, kwargs, message", [
    (lambda p: (np.empty((0, 3)), {}), {}, "no points to show"),
    (lambda p: (p[:, :2], {}), {}, "points must have shape (n, 3), got (2000, 2)"),
    (lambda p: (np.full((5, 3), np.nan), {}), {}, "none of the 5 points has finite coordinates"),
    (lambda p: (p, {"mean": p[:10, 0]}), {}, "field 'mean' must have shape (2000,) or (2000, 3), got (10,)"),
    (lambda p: (p, {"name": np.array(["a"] * 2000)}), {}, "field 'name' must hold numbers"),
    (lambda p: (p, {"mean": p[:, 0]}), {"field": "k1"}, "no field 'k1' to show; the fields are mean, x, y, z"),
    (lambda p: (p, {}), {"coordinates": False}, "no field to colour by"),
    (lambda p: (p, {}), {"max_points": 0}, "max_points = 0 is outside its range"),
    (lambda p: (p, {}), {"normals": np.ones((3, 3))}, "normals must be numbers of shape (2000, 3)"),
    (lambda p: (p, {}), {"percentiles": (50, 10)}, "percentiles must satisfy 0 <= LOW < HIGH <= 100"),
])
def test_bad_input_is_one_clear_error_and_no_file(tmp_path, cloud, args, kwargs, message):
    points, given = args(cloud[0])
    path = tmp_path / "view.html"
    path.write_text("the page of an earlier run")
    with pytest.raises(HeatcurvError) as error:
        write_view(points, given, path, **kwargs)
    assert message in str(error.value) and "\n" not in str(error.value)
    assert path.read_text() == "the page of an earlier run"
    assert [p.name for p in tmp_path.iterdir()] == ["view.html"]


def test_bad_paths(tmp_path, cloud):
    points, _ = cloud
    with pytest.raises(HeatcurvError, match=r"a view is an HTML page, give a name ending in \.html"):
        write_view(points, {}, tmp_path / "view.png")
    with pytest.raises(HeatcurvError, match="does not exist"):
        write_view(points, {}, tmp_path / "missing" / "view.html")
    assert list(tmp_path.iterdir()) == []


def test_a_page_too_big_for_a_browser_is_refused_before_it_is_built(tmp_path, monkeypatch):
    import heatcurv.view

    points = np.random.default_rng(0).uniform(-1, 1, (20_000, 3))
    fields = {name: points[:, 0] for name in ("a", "b", "c")}
    # 4/3 * (12 + 3 * 4) = 32 characters a point, 640000 in all
    monkeypatch.setattr(heatcurv.view, "MAX_DATA_CHARS", 600_000)
    with pytest.raises(HeatcurvError, match=r"20000 points with 3 field\(s\) make a page of about 1 MB, more than a "
                                            r"browser can read .*show at most about 17812 points"):
        write_view(points, fields, tmp_path / "big.html")
    assert list(tmp_path.iterdir()) == []
    view = write_view(points, fields, tmp_path / "fits.html", max_points=17812)
    assert 0.95 * 600_000 < len(DATA_BLOCK_TEXT.search(view.path.read_text()).group(1)) < 600_000


def test_a_field_without_a_finite_value_is_drawn_grey(tmp_path, cloud):
    points, _ = cloud
    view = write_view(points, {"empty": np.full(2000, np.nan), "mean": points[:, 0]}, tmp_path / "v.html")
    assert view.limits["empty"] is None and view.limits["mean"][2] == "signed"
    entry = page_block(view.path)["fields"][0]
    assert entry["kind"] == "none" and entry["low"] is None and np.isnan(field(page_block(view.path), "empty")).all()
