"""heatcurv.cli.picture: ``heatcurv render`` reads a field from the file or computes it."""

import numpy as np
import pytest
from cli_helpers import read_image, run

from heatcurv import io, surfaces
from heatcurv.data import bunny_path


def colours_of(image) -> np.ndarray:
    """Distinct RGB colours of an image, as uint8 rows."""
    pixels = np.round(np.asarray(image)[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    return np.unique(pixels, axis=0)


@pytest.fixture(scope="module")
def bunny_fields(tmp_path_factory):
    directory = tmp_path_factory.mktemp("render")
    path = directory / "bunny_fields.ply"
    out = run("compute", bunny_path(), "-o", path, "-q")
    assert out.returncode == 0, out.stderr
    return path


def test_render_reads_a_computed_field_without_recomputing(tmp_path, bunny_fields):
    out = run(
        "render", bunny_fields, "-o", tmp_path / "bunny.png", "--field", "mean", "--views", "2", "--size", "1200x600"
    )
    assert out.returncode == 0, out.stderr
    assert "field 'mean' read from" in out.stdout and "estimated" not in out.stdout
    image = read_image(tmp_path / "bunny.png")
    assert image.shape[:2] == (600, 1200)
    colours = colours_of(image).astype(int)
    # a diverging map on a signed field: clearly red and clearly blue points
    assert np.any((colours[:, 0] > 180) & (colours[:, 2] < 90))
    assert np.any((colours[:, 2] > 180) & (colours[:, 0] < 120))
    assert len(colours) > 300


def test_render_computes_a_field_a_raw_cloud_lacks(tmp_path):
    sample = surfaces.Sphere().sample(2000, "random", seed=5)
    io.write_points(tmp_path / "sphere.xyz", sample.points)
    out = run(
        "render", tmp_path / "sphere.xyz", "-o", tmp_path / "area.png", "--field", "area", "--size", "500x400",
        "--range", "0,0.02",
    )
    assert out.returncode == 0, out.stderr
    assert "estimated curvature" in out.stdout and "colours 0 .. 0.02 length²" in out.stdout
    assert read_image(tmp_path / "area.png").shape[:2] == (400, 500)


@pytest.mark.parametrize("field, computed", [("mean", False), ("mean_se", True)])
def test_render_computes_the_standard_errors_only_to_draw_one(tmp_path, monkeypatch, field, computed):
    from heatcurv import estimator
    from heatcurv.cli.main import main

    sample = surfaces.Sphere().sample(2000, "random", seed=5)
    io.write_points(tmp_path / "sphere.xyz", sample.points)
    seen = []
    real = estimator.estimate
    monkeypatch.setattr(estimator, "estimate", lambda *a, **k: seen.append(k.get("se", True)) or real(*a, **k))
    assert main(["render", str(tmp_path / "sphere.xyz"), "-o", str(tmp_path / f"{field}.png"), "--field", field,
                 "--size", "300x200", "-q"]) == 0
    assert seen == [computed] and read_image(tmp_path / f"{field}.png").shape[:2] == (200, 300)


def test_render_labels_the_colour_bar_with_the_unit_and_colours_one_sign_from_the_data(tmp_path):
    sample = surfaces.Sphere(radius=2.0).sample(2000, "random", seed=5)
    io.write_points(tmp_path / "sphere.xyz", sample.points)
    out = run("render", tmp_path / "sphere.xyz", "-o", tmp_path / "mean.svg", "--field", "mean", "--size", "500x400",
              "--unit", "mm")
    assert out.returncode == 0, out.stderr
    # mean curvature 1/2 everywhere: limits about 0.5 .. 0.5, not -0.5 .. 0.5
    low, high = (float(v) for v in out.stdout.rsplit("colours ", 1)[1].split(" 1/mm")[0].split(" .. "))
    assert 0.45 < low <= high < 0.55  # printed to 4 digits
    assert "<!-- mean curvature (1/mm) -->" in (tmp_path / "mean.svg").read_text()  # the colour bar's label


def test_render_errors(tmp_path, bunny_fields, capsys):
    from heatcurv.cli import main

    out = run("render", bunny_fields, "-o", tmp_path / "p.png", "--field", "temperature")
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "Traceback" not in out.stderr
    assert out.stderr.startswith("heatcurv: error: ")
    assert "has no field 'temperature' and heatcurv does not compute it" in out.stderr
    cases = [  # the same in this process
        (["--size", "20x20"], "argument --size"),
        (["--views", "0"], "argument --views"),
        (["--range", "1,1"], "LOW < HIGH"),
        (["--cmap", "rainbowish"], "unknown colour map 'rainbowish'"),
        (["-o", str(tmp_path / "picture.docx")], "unknown picture extension '.docx'"),
    ]
    for extra, message in cases:
        args = ["render", str(bunny_fields)] + (extra if "-o" in extra else ["-o", str(tmp_path / "p.png")] + extra)
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("heatcurv: error: ") and message in err
    assert list(tmp_path.iterdir()) == []


def test_render_draws_unreliable_points_grey(tmp_path, bunny_fields):
    cloud = io.read_points(bunny_fields)
    unreliable = int((cloud.fields["reliable"] == 0).sum())
    assert unreliable > 0
    grey = run("render", bunny_fields, "-o", tmp_path / "grey.png", "--field", "mean", "--size", "600x400")
    assert grey.returncode == 0, grey.stderr
    assert f"{unreliable} unreliable point(s) drawn grey" in grey.stdout
    coloured = run("render", bunny_fields, "-o", tmp_path / "all.png", "--field", "mean", "--size", "600x400",
                   "--unreliable", "coloured")
    assert coloured.returncode == 0 and "drawn grey" not in coloured.stdout
    # the colour range comes from the reliable points only: the unreliable ones hold the extremes
    limits = [float(o.stdout.rsplit("colours ", 1)[1].split(" ..")[0]) for o in (grey, coloured)]
    assert abs(limits[0]) < abs(limits[1])
    # a mask field or an input property is drawn as it is
    mask = run("render", bunny_fields, "-o", tmp_path / "mask.png", "--field", "reliable", "--size", "600x400")
    assert mask.returncode == 0 and "drawn grey" not in mask.stdout


def test_render_shades_by_default_and_no_shade_draws_flat_colours(tmp_path, bunny_fields):
    dark = {}
    for flag in ([], ["--no-shade"]):
        name = "flat" if flag else "shaded"
        out = run("render", bunny_fields, "-o", tmp_path / f"{name}.png", "--field", "mean", "--size", "900x600",
                  "--title", "", "-v", *flag)
        assert out.returncode == 0, out.stderr
        assert ("flat colours" if flag else "shaded by the normals") in out.stdout
        assert "facing away behind the near side hidden" in out.stdout  # the far side of the bunny
        rgb = read_image(tmp_path / f"{name}.png")[:, :600, :3]  # the bunny, left of the colour bar
        drawn = (rgb < 0.97).any(axis=2)
        # brightest channel below 0.45: darker than any colour of coolwarm (or a blend of two)
        dark[name] = float(np.mean(rgb[drawn].max(axis=1) < 0.45))
    assert dark["flat"] == 0.0 and dark["shaded"] > 0.1
