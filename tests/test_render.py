"""Pictures: heatcurv.render.render_field and its steps (``heatcurv render``: tests/cli/test_cli_picture.py)."""

import subprocess
import sys

import numpy as np
import pytest

import heatcurv
from heatcurv import render, shading, surfaces
from heatcurv.render import camera_frames, colour_limits, render_field


def read_image(path):
    from matplotlib.image import imread

    return imread(path)


def colours_of(image) -> np.ndarray:
    """Distinct RGB colours of an image, as uint8 rows."""
    pixels = np.round(np.asarray(image)[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    return np.unique(pixels, axis=0)


@pytest.fixture(scope="module")
def torus():
    sample = surfaces.Torus().sample(3000, "random", seed=2)
    return sample, heatcurv.estimate(sample.points)


# ----------------------------------------------------------------------------- render_field


def test_png_of_the_requested_size_and_not_blank(tmp_path, torus):
    sample, res = torus
    out = render_field(
        sample.points, res.mean, tmp_path / "torus.png", field="mean", size=(640, 480), normals=res.normals
    )
    image = read_image(tmp_path / "torus.png")
    assert image.shape in ((480, 640, 3), (480, 640, 4))
    assert out.size == (640, 480) and out.drawn == out.total == 3000
    assert len(colours_of(image)) > 200
    # mean curvature > 0 everywhere on the torus: the sequential map over the values' own range
    assert res.mean.min() > 0 and out.kind == "sequential"
    assert out.limits == pytest.approx(tuple(np.percentile(res.mean, [2, 98])))
    rgb = np.asarray(image)[..., :3].reshape(-1, 3)
    yellowish = (rgb[:, 0] > 0.6) & (rgb[:, 1] > 0.6) & (rgb[:, 2] < 0.4)  # viridis' high end
    reddish = (rgb[:, 0] > 0.6) & (rgb[:, 1] < 0.4) & (rgb[:, 2] < 0.4)  # coolwarm's positive end
    assert yellowish.mean() > 0.005 and reddish.mean() < 0.001
    assert list(tmp_path.iterdir()) == [tmp_path / "torus.png"]  # no temporary file left


def test_several_views_and_vector_formats(tmp_path, torus):
    sample, res = torus
    for name in ("views.svg", "views.pdf"):
        render_field(sample.points, res.k2, tmp_path / name, field="k2", views=4, size=(900, 600))
        assert (tmp_path / name).stat().st_size > 1000
    assert (tmp_path / "views.svg").read_text().lstrip().startswith("<?xml")
    assert (tmp_path / "views.pdf").read_bytes().startswith(b"%PDF")


def test_large_clouds_are_subsampled(tmp_path):
    points = surfaces.Sphere().sample(5000, "fibonacci").points
    out = render_field(points, points[:, 2], tmp_path / "sub.png", field="z", max_points=1000, size=(300, 300))
    assert out.drawn == 1000 and out.total == 5000


def test_nan_values_and_coordinates_are_drawn_grey_or_skipped(tmp_path):
    points = surfaces.Sphere().sample(2000, "fibonacci").points.copy()
    values = points[:, 0].copy()
    values[:500] = np.nan
    points[-3:] = np.nan
    out = render_field(points, values, tmp_path / "nan.png", field="x", size=(300, 300))
    assert out.drawn == 1997
    assert len(colours_of(read_image(tmp_path / "nan.png"))) > 20


def test_errors_leave_no_file(tmp_path):
    points = surfaces.Sphere().sample(500, "fibonacci").points
    cases = [
        (dict(path=tmp_path / "a.bmpx"), "unknown picture extension"),
        (dict(path=tmp_path / "no" / "a.png"), "does not exist"),
        (dict(size=(50, 50)), "picture size"),
        (dict(values=np.full(500, np.nan)), "no finite values"),
        (dict(values=np.zeros(7)), "shape (500,)"),
        (dict(cmap="not-a-map"), "unknown colour map"),
        (dict(value_range=(1, -1)), "LOW < HIGH"),
        (dict(up=(0, 0, 0)), "up must be 3 finite numbers"),
    ]
    for changes, message in cases:
        arguments = dict(path=tmp_path / "a.png", values=points[:, 2], size=(300, 300))
        arguments.update(changes)
        path, values = arguments.pop("path"), arguments.pop("values")
        with pytest.raises(heatcurv.HeatcurvError, match=message.replace("(", r"\(").replace(")", r"\)")):
            render_field(points, values, path, **arguments)
    assert list(tmp_path.iterdir()) == []


def test_rendering_leaves_pyplot_and_the_backend_alone():
    # no pyplot, no matplotlib.use(): an interactive session's backend stays as it was
    code = (
        "import matplotlib, sys, tempfile, os, numpy as np\n"
        "backend = dict.__getitem__(matplotlib.rcParams, 'backend')\n"
        "from heatcurv.render import render_field\n"
        "p = np.random.default_rng(0).normal(size=(300, 3))\n"
        "render_field(p, p[:, 0], os.path.join(tempfile.mkdtemp(), 'a.png'), field='x', size=(200, 200))\n"
        "assert 'matplotlib.pyplot' not in sys.modules\n"
        "assert dict.__getitem__(matplotlib.rcParams, 'backend') == backend\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr


# ----------------------------------------------------------------------------- colours and camera


def test_colour_limits():
    rng = np.random.default_rng(0)
    signed = np.concatenate([rng.uniform(-1, 3, 1000), [np.nan, 50.0]])
    low, high, kind = colour_limits(signed, "signed")
    assert kind == "signed" and low == -high and high == pytest.approx(np.nanpercentile(signed, 98))
    low, high, kind = colour_limits(rng.uniform(1, 2, 1000))  # one sign: sequential
    assert kind == "sequential" and 1.0 < low < 1.05 and 1.95 < high < 2.0
    assert colour_limits(rng.normal(size=100))[2] == "signed"  # both signs: diverging
    assert colour_limits(np.array([0, 1, 1, 0], dtype=np.uint8))[2] == "mask"
    assert colour_limits(rng.normal(size=100), value_range=(-0.5, 2.0)) == (-0.5, 2.0, "signed")
    assert colour_limits(rng.normal(size=100), "signed", value_range=(0.5, 2.0)) == (0.5, 2.0, "sequential")
    assert colour_limits(np.full(10, 3.0), "sequential")[:2] == pytest.approx((2.97, 3.03))
    assert colour_limits(np.zeros(10), "signed") == (-1.0, 1.0, "signed")  # zero: the neutral colour


def test_colour_limits_of_a_signed_field_of_one_sign_come_from_its_data(torus):
    # the torus (r1 = 1, r2 = 2.3701): mean curvature from 0.135 (inner equator) to 0.648 (outer), all positive
    sample, res = torus
    mean = res.mean
    assert 0.13 < sample.mean.min() < mean.min() and mean.max() < 0.66
    low, high, kind = colour_limits(mean, "signed")
    assert kind == "sequential" and low != -high
    assert (low, high) == pytest.approx(tuple(np.percentile(mean, [2, 98])))
    assert 0.13 < low < 0.16 and 0.63 < high < 0.66  # the bar spans the values' spread, not -0.65..0.65
    # all negative (inward normals): the same, mirrored
    low, high, kind = colour_limits(-mean, "signed")
    assert kind == "sequential" and (low, high) == pytest.approx(tuple(np.percentile(-mean, [2, 98])))
    assert -0.66 < low < -0.63 and -0.16 < high < -0.13
    # a few negative values below the 2nd percentile do not make it diverging
    outliers = mean.copy()
    outliers[:30] = -5.0  # 1 % of the points
    low, high, kind = colour_limits(outliers, "signed")
    assert kind == "sequential" and 0.13 < low < 0.2 and 0.63 < high < 0.66
    # values that change sign within the robust range: symmetric about zero
    changing = mean - 0.3
    low, high, kind = colour_limits(changing, "signed")
    bound = np.abs(np.percentile(changing, [2, 98])).max()
    assert kind == "signed" and (low, high) == pytest.approx((-bound, bound))
    # heatcurv's signed fields are diverging only when they change sign; the others never are
    assert colour_limits(mean, render.field_style("mean").kind)[2] == "sequential"
    assert colour_limits(changing, render.field_style("k1").kind)[2] == "signed"
    assert colour_limits(changing, render.field_style("area").kind)[2] == "sequential"


def test_the_colour_bar_label_carries_the_unit(tmp_path, torus):
    sample, res = torus
    labels = {"mean": "mean curvature (1/mm)", "gaussian": "Gaussian curvature (1/mm²)",
              "k1": "maximal principal curvature k1 (1/mm)", "area": "area per point (mm²)",
              "feature_score": "feature score (turning angle) (degrees)", "reliable": "reliable"}
    for name, label in labels.items():
        assert render.field_style(name).bar_label("mm") == label
    assert render.field_style("mean").bar_label() == "mean curvature (1/length)"
    out = render_field(sample.points, res.gaussian, tmp_path / "g.svg", field="gaussian", size=(500, 400),
                       length_unit="mm", normals=res.normals)
    assert out.label == "Gaussian curvature (1/mm²)"
    # matplotlib's SVG draws text as paths, each text preceded by a comment holding it
    svg = (tmp_path / "g.svg").read_text()
    assert "<!-- Gaussian curvature (1/mm²) -->" in svg
    assert "<!-- Gaussian curvature -->" in svg  # the title, without the unit
    other = render.FieldStyle("temperature", "K")  # a quantity heatcurv does not name, with its unit
    out = render_field(sample.points, sample.points[:, 2] + 300, tmp_path / "t.svg", field=other, size=(400, 300))
    assert out.label == "temperature (K)" and out.kind == "sequential"
    assert "<!-- temperature (K) -->" in (tmp_path / "t.svg").read_text()
    with pytest.raises(heatcurv.HeatcurvError, match="no finite values"):
        colour_limits(np.full(3, np.nan))


def test_camera_looks_along_the_thinnest_direction():
    rng = np.random.default_rng(1)
    disc = rng.normal(size=(2000, 3)) * [3.0, 0.1, 1.0]  # thin along y
    frames = camera_frames(disc)
    right, up, toward = frames[0]
    assert abs(toward[1]) > 0.99  # camera on the y axis
    np.testing.assert_allclose(frames[0] @ frames[0].T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.cross(up, toward), right, atol=1e-12)  # no mirror image
    assert up[2] > 0.99  # y is the view direction, so z is up
    # the side most normals face
    normals = np.tile([0.0, -1.0, 0.0], (2000, 1))
    assert camera_frames(disc, normals=normals)[0, 2, 1] < -0.99
    # views turn about the up axis
    four = camera_frames(disc, 4)
    np.testing.assert_allclose(four[:, 1], np.tile(four[0, 1], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(four[2, 2], -four[0, 2], atol=1e-12)
    np.testing.assert_allclose(four[1, 2] @ four[0, 2], 0.0, atol=1e-12)


# ----------------------------------------------------------------------------- the steps of render_field


def test_drawn_subset_drops_nonfinite_points_and_subsamples():
    points = np.arange(30.0).reshape(10, 3)
    points[[2, 7]] = np.nan
    values = np.arange(10)
    normals = np.tile([0.0, 0.0, 1.0], (10, 1))
    normals[4] = np.nan
    keep, xyz, shown, kept_normals = render._drawn_subset(points, values, normals, 100, 0)
    np.testing.assert_array_equal(keep, [0, 1, 3, 4, 5, 6, 8, 9])
    np.testing.assert_array_equal(xyz, points[keep])
    assert shown.dtype == np.float64 and np.array_equal(shown, keep)
    assert kept_normals.shape == (8, 3)  # row for row with the points drawn
    assert np.isnan(kept_normals[3]).all() and np.isfinite(np.delete(kept_normals, 3, axis=0)).all()
    scaled = render._drawn_subset(points, values, normals * 5.0, 100, 0)[3]  # scaled to unit length
    np.testing.assert_allclose(np.delete(scaled, 3, axis=0), np.tile([0.0, 0.0, 1.0], (7, 1)))
    zero = render._drawn_subset(points, values, np.zeros((10, 3)), 100, 0)[3]
    assert np.isnan(zero).all()  # a zero normal has no direction
    keep, _, _, none = render._drawn_subset(points, values, normals[:5], 3, 0)  # wrong shape: no normals
    assert keep.size == 3 and np.all(np.diff(keep) > 0) and none is None
    np.testing.assert_array_equal(keep, render._drawn_subset(points, values, None, 3, 0)[0])  # seeded
    with pytest.raises(heatcurv.HeatcurvError, match="nothing to draw"):
        render._drawn_subset(np.full((3, 3), np.nan), np.zeros(3), None, 10, 0)


def test_colour_mapping_by_kind():
    from matplotlib import colors as mcolors

    colour_map, norm = render._colour_mapping("mask", -0.5, 1.5)
    assert isinstance(norm, mcolors.BoundaryNorm)
    assert mcolors.to_hex(colour_map(norm(1))) == render.MASK_COLOURS[1]
    assert isinstance(render._colour_mapping("signed", -1.0, 2.0)[1], mcolors.TwoSlopeNorm)
    colour_map, norm = render._colour_mapping("signed", -1.0, 1.0)
    assert type(norm) is mcolors.Normalize and colour_map.name.startswith(render.DIVERGING_CMAP)
    colour_map, _ = render._colour_mapping("sequential", 0.0, 1.0)
    assert colour_map.name.startswith(render.SEQUENTIAL_CMAP)
    assert mcolors.to_hex(colour_map(np.ma.masked_invalid([np.nan]))[0]) == render.MISSING_COLOUR
    with pytest.raises(heatcurv.HeatcurvError, match="unknown colour map"):
        render._colour_mapping("sequential", 0.0, 1.0, "not-a-map")


def test_projection_and_layout_fit_the_picture():
    xyz = np.random.default_rng(0).normal(size=(500, 3)) * [4.0, 1.0, 0.1]  # wide, flat
    frames = camera_frames(xyz, 2)
    screens, middles, span = render._project(xyz, frames)
    assert len(screens) == len(middles) == 2 and screens[0].shape == (500, 3)
    assert np.all(span >= np.ptp(screens[0][:, :2], axis=0) * 1.04 - 1e-12)
    layout = render._layout(2, span, 1600, 1000, 100, None)
    assert layout.rows * layout.cols >= 2
    assert (layout.panel_w, layout.panel_h) == pytest.approx((layout.scale * span[0], layout.scale * span[1]))
    assert 0 < layout.left and layout.left + layout.block_w + 0.2 + 0.16 < layout.fig_w  # panels and colour bar fit
    assert layout.top <= layout.fig_h and layout.top - layout.block_h >= 0
    assert render._layout(2, span, 1600, 1000, 100, "").area_h > layout.area_h  # no title: more room


def test_disc_pixels():
    points = surfaces.Sphere().sample(2000, "fibonacci").points
    assert render._disc_pixels(points, 7, 1.0, 100) == 7.0
    assert render._disc_pixels(points, None, 1e-9, 100) == 1.0  # clipped to 1..80 pixels
    assert render._disc_pixels(points, None, 1e9, 100) == 80.0
    assert render._disc_pixels(points[:5], None, 1.0, 100) == 3.0  # too few points to measure


def test_check_picture_path(tmp_path):
    path, ext = render._check_picture_path(str(tmp_path / "a.PNG"))
    assert path == tmp_path / "a.PNG" and ext == ".png"
    with pytest.raises(heatcurv.HeatcurvError, match="unknown picture extension"):
        render._check_picture_path(tmp_path / "a.bmpx")


@pytest.mark.parametrize(
    "options, message",
    [
        ({"dpi": float("nan")}, r"^dpi must be a whole number in \[10, 2400\], got nan$"),
        ({"dpi": 1e30}, r"^dpi = 1e\+30 is outside its range \[10, 2400\]"),
        ({"max_points": float("nan")}, r"^max_points must be a whole number"),
        ({"views": 10**9}, r"^views = 1000000000 is outside its range \[1, 36\]"),
        ({"point_size": -1.0}, r"^point_size = -1 is outside its range \[0.01, 1000\]"),
        ({"size": (float("nan"), 500)}, r"^the picture size must be 100-10000 whole pixels each way"),
        ({"size": "big"}, r"^size must be two numbers"),
        ({"elevation": float("inf")}, r"^elevation must be a number in \[-90, 90\], got inf$"),
        ({"seed": -3}, r"^seed = -3 is outside its range"),
    ],
)
def test_every_number_of_a_picture_is_range_checked(tmp_path, options, message):
    # before: dpi or max_points of NaN raised numpy/int() ValueErrors, views = 1e9 tried to draw them
    pts = heatcurv.surfaces.Sphere().sample(200, "random", seed=1).points
    with pytest.raises(heatcurv.HeatcurvError, match=message):
        render_field(pts, pts[:, 0], tmp_path / "x.png", **options)
    assert not list(tmp_path.iterdir())


# ----------------------------------------------------------------------------- shading and hidden points


def panel_pixels(image):
    """RGB of the first panel of a picture without title: the columns left of the first all-white gap."""
    rgb = np.asarray(image)[..., :3]
    used = (rgb < 0.97).any(axis=2)
    columns = np.flatnonzero(used.any(axis=0))
    gap = np.flatnonzero(np.diff(columns) > 1)
    last = columns[gap[0]] if gap.size else columns[-1]
    return rgb[:, : last + 1], used[:, : last + 1]


def test_shading_lights_the_side_facing_the_light(tmp_path):
    sphere = surfaces.Sphere().sample(6000, "fibonacci")
    everywhere = np.ones(6000, dtype=bool)  # a mask: one colour, red
    brightness = {}
    for shade in (True, False):
        out = render_field(
            sphere.points, everywhere, tmp_path / f"{shade}.png", field="feature", size=(600, 400), title="",
            normals=sphere.normals, view=(0, 0, 1), up=(0, 1, 0), shade=shade,
        )
        assert out.shading == ("normals" if shade else "flat")
        rgb, used = panel_pixels(read_image(tmp_path / f"{shade}.png"))
        rows, cols = np.nonzero(used)
        centre = np.array([rows.min() + rows.max(), cols.min() + cols.max()]) / 2
        radius = (rows.max() - rows.min()) / 2
        red = []
        for right, up in (shading.LIGHT[:2], (0.55, -0.73)):  # mean red of a 5x5 patch there on the sphere's disc
            row, col = np.round(centre + radius * np.array([-up, right])).astype(int)
            red.append(float(rgb[row - 2 : row + 3, col - 2 : col + 3, 0].mean()))
        brightness[shade] = tuple(red)
    lit, limb = brightness[True]  # where the normal is the light's direction; the lower right limb
    assert lit / limb > 2.0
    assert limb == pytest.approx(shading.AMBIENT * 214 / 255, abs=0.03)
    flat_lit, flat_limb = brightness[False]
    assert flat_lit == pytest.approx(214 / 255, abs=0.01) and flat_limb == pytest.approx(flat_lit, abs=0.01)


def test_the_far_side_never_shows_through_the_near_side(tmp_path):
    # a torus seen from the top: the upper half is the near side (+1, red), the lower half the far side (-1, blue)
    torus = surfaces.Torus().sample(6000, "random", seed=3)
    near = np.where(torus.points[:, 2] > 0, 1.0, -1.0)
    counts = {}
    for name, normals in (("normals", torus.normals), ("inward", -torus.normals), ("none", None)):
        out = render_field(
            torus.points, near, tmp_path / f"{name}.png", field="side", size=(700, 600), title="", normals=normals,
            view=(0, 0, 1), up=(0, 1, 0),
        )
        rgb, used = panel_pixels(read_image(tmp_path / f"{name}.png"))
        rows, cols = np.nonzero(used)
        centre = np.array([rows.min() + rows.max(), cols.min() + cols.max()]) / 2
        outer = (rows.max() - rows.min()) / 2  # radius r1 + r2 = 3.37 on the picture
        grid = np.indices(used.shape).transpose(1, 2, 0)
        distance = np.linalg.norm(grid - centre, axis=2) / outer * 3.3701
        covered = (distance > 1.6) & (distance < 3.1)  # the ring the near side covers, outlines left out
        blue = (rgb[..., 2] > rgb[..., 0] + 0.15) & covered
        red = (rgb[..., 0] > rgb[..., 2] + 0.15) & covered
        counts[name] = (int(blue.sum()), int(red.sum()), out.hidden)
    for name in ("normals", "inward"):  # either orientation of the normals hides the far side
        blue, red, hidden = counts[name]
        assert blue == 0 and red > 0.95 * np.count_nonzero(covered)
        assert 2700 < hidden[0] < 3300  # about half the points
    blue, red, hidden = counts["none"]  # without normals nothing is hidden: the far side shows through gaps
    assert hidden == (0,) and blue > 50


def test_shade_off_draws_the_flat_colours_of_the_colour_bar(tmp_path):
    sphere = surfaces.Sphere().sample(4000, "fibonacci")
    counts = {}
    for shade in (True, False):
        render_field(
            sphere.points, np.ones(4000, dtype=bool), tmp_path / f"{shade}.png", field="reliable", size=(500, 400),
            title="", normals=sphere.normals, shade=shade,
        )
        rgb, used = panel_pixels(read_image(tmp_path / f"{shade}.png"))
        exact = np.all(np.abs(np.round(rgb * 255) - [214, 39, 40]) <= 1, axis=2)  # MASK_COLOURS[1]
        counts[shade] = exact.sum() / used.sum()
    assert counts[False] > 0.95  # all but the outline's anti-aliased pixels
    assert counts[True] < 0.2


def test_without_normals_the_points_are_shaded_from_fitted_normals(tmp_path):
    sphere = surfaces.Sphere().sample(3000, "fibonacci")
    fitted = shading.estimated_normals(sphere.points)
    assert np.min(np.abs(np.sum(fitted * sphere.normals, axis=1))) > 0.99  # either sign
    assert shading.estimated_normals(sphere.points[:3]) is None
    out = render_field(sphere.points, sphere.points[:, 0], tmp_path / "a.png", field="x", size=(300, 300))
    assert out.shading == "estimated normals" and out.hidden == (0,)
    tiny = render_field(sphere.points[:3], [1.0, 2.0, 3.0], tmp_path / "b.png", field="x", size=(300, 300))
    assert tiny.shading == "flat"


def test_shade_is_two_sided_lambert_light():
    rgba = np.tile([0.8, 0.4, 0.2, 0.5], (5, 1))
    side = np.cross(shading.LIGHT, [0.0, 0.0, 1.0])
    normals = np.array([shading.LIGHT, -shading.LIGHT, side / np.linalg.norm(side), [0, 0, 1.0], [np.nan] * 3])
    shaded = shading.shade_colours(rgba, normals)
    factor = shaded[:, 0] / 0.8
    ambient, facing = shading.AMBIENT, shading.AMBIENT + (1 - shading.AMBIENT) * shading.LIGHT[2]
    np.testing.assert_allclose(factor, [1.0, 1.0, ambient, facing, facing])
    np.testing.assert_allclose(shaded[:, :3], rgba[:, :3] * factor[:, None])
    np.testing.assert_array_equal(shaded[:, 3], 0.5)


def test_hidden_back_faces_of_closed_and_open_clouds():
    sphere = surfaces.Sphere().sample(4000, "fibonacci")
    screen = sphere.points[:, [0, 1, 2]]  # camera on +z
    facing = sphere.normals[:, 2]
    diameter = 0.06
    outward = shading.hidden_back_faces(screen, facing, diameter)
    assert np.all(facing[outward] < 0) and np.all(screen[outward, 2] < 0)
    assert outward.sum() > 0.9 * np.sum(facing < 0)  # the far half, but for its outline
    np.testing.assert_array_equal(shading.hidden_back_faces(screen, -facing, diameter), outward)  # inward normals
    cap = screen[:, 2] < 0  # an open cap seen from behind: nothing in front of it, nothing hidden
    assert not shading.hidden_back_faces(screen[cap], facing[cap], diameter).any()
    unknown = facing.copy()
    unknown[:] = np.nan
    assert not shading.hidden_back_faces(screen, unknown, diameter).any()


def test_the_names_other_modules_import_from_render_stay_there():
    # heatcurv.view and the command line import these from heatcurv.render; the lighting moved to heatcurv.shading
    for name in ("DIVERGING_CMAP", "SEQUENTIAL_CMAP", "MASK_COLOURS", "MISSING_COLOUR", "PICTURE_RANGES",
                 "camera_frames", "colour_limits", "field_style", "render_field", "supported_picture_formats"):
        assert hasattr(render, name), name
    for name in ("AMBIENT", "LIGHT", "HIDDEN_DEPTH"):
        assert getattr(render, name) is getattr(shading, name), name


def test_grey_unreliable_turns_only_the_unreliable_values_into_nan():
    from heatcurv.render import grey_unreliable

    out = grey_unreliable(np.array([1.0, -2.0, 3.0]), np.array([True, False, True]))
    assert out[0] == 1.0 and np.isnan(out[1]) and out[2] == 3.0
