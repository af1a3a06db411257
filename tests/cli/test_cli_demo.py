"""heatcurv.cli.demo: ``heatcurv demo`` on an analytic surface and on the bunny scan."""

import re

from cli_helpers import distinct_colours, read_image, run

from heatcurv.data import BUNNY_ATTRIBUTION, bunny_path


def test_demo_prints_an_error_table(tmp_path, records):
    out = run("demo", "--surface", "sphere", "-n", "3000", "--sampler", "fibonacci", "--no-picture", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "sphere, 3000 points" in out.stdout
    rows = {line.split()[0]: line.split() for line in out.stdout.splitlines() if re.match(r"^(default|paper) ", line)}
    assert set(rows) == {"default", "paper"}
    # columns: mean k1 k2 gauss area (total, %) d1 normal orient time; sphere: the paper's < 1 %
    assert float(rows["paper"][1]) < 1.0
    records.check(
        "cli_demo/sphere-fibonacci-3000", default_mean=float(rows["default"][1]),
        paper_mean=float(rows["paper"][1]), paper_area=float(rows["paper"][5]),
    )
    assert rows["default"][8] == "100.00%"
    assert list(tmp_path.iterdir()) == []  # --no-picture


def test_demo_default_on_a_random_cloud_writes_a_picture(tmp_path, records):
    # the default example: random sampling, where the paper's areas fail
    out = run("demo", "-n", "6000", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    rows = {line.split()[0]: line.split() for line in out.stdout.splitlines() if re.match(r"^(default|paper) ", line)}
    assert float(rows["paper"][5]) < -20  # the paper's areas fail here
    records.check(
        "cli_demo/torus-random-6000", default_mean=float(rows["default"][1]),
        default_area=float(rows["default"][5]), paper_area=float(rows["paper"][5]),
    )
    assert "wrote heatcurv_demo.png" in out.stdout
    image = read_image(tmp_path / "heatcurv_demo.png")
    assert image.shape[:2] == (1000, 1400) and distinct_colours(image) > 100


def test_demo_on_the_bunny(tmp_path):
    out = run("demo", "--bunny", "-o", "bunny.png", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "1839 points" in out.stdout and BUNNY_ATTRIBUTION in out.stdout
    image = read_image(tmp_path / "bunny.png")
    assert image.shape[:2] == (800, 1600) and distinct_colours(image) > 100


def test_the_bunny_ships_with_its_attribution():
    path = bunny_path()
    header = path.read_bytes()[:400].decode("ascii")
    assert f"comment {BUNNY_ATTRIBUTION}\n" in header
    assert "element vertex 1839" in header
    assert (path.parent / "README.md").is_file()
