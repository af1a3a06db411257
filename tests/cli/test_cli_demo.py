"""heatcurv.cli.demo: ``heatcurv demo`` on an analytic surface and on the bunny scan."""

import re

from cli_helpers import distinct_colours, read_image, run, stderr_lines

import heatcurv
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
    # a regular sample: the paper's method does not warn, and the demo has nothing to explain
    assert "The paper's method" not in out.stdout and stderr_lines(out) == []


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


PAPER_SENTENCE = (
    "The paper's method is made for regular, clean samples and warned about this random one: its\n"
    "errors above are the method's, not a fault (--verbose prints its warnings; --surface sphere\n"
    "--sampler fibonacci gives it a regular sample).\n"
)


def test_demo_says_calmly_what_the_paper_methods_errors_mean(tmp_path):
    """What was computed, the errors, one sentence on the paper's method: its warnings only with --verbose."""
    out = run("demo", "-n", "3000", "--no-picture", cwd=tmp_path)
    assert out.returncode == 0 and stderr_lines(out) == [], out.stderr
    lines = out.stdout.splitlines()
    assert lines[:2] == [
        f"heatcurv {heatcurv.__version__} demo: torus, 3000 points (random sampler, no noise)",
        "methods: default (built for irregular, scanned and noisy clouds) and paper (the paper's, literally)",
    ]
    assert lines[2:5] == ["", "relative L1 error (%) on interior points; angles in degrees", lines[4]]
    assert [line.split()[0] for line in lines[5:7]] == ["default", "paper"]
    assert "\n".join(lines[7:]) + "\n" == (
        "\narea: relative error of the total (open surfaces: biased by the border).\n"
        "the default's kernel here: chord-60, noise estimate 0.00029.\n" + PAPER_SENTENCE
    )
    assert "warning:" not in out.stdout and "unreliable" not in out.stdout and "note" not in out.stdout
    verbose = run("demo", "-n", "3000", "--no-picture", "--verbose", cwd=tmp_path)
    assert PAPER_SENTENCE in verbose.stdout
    warned = [line for line in verbose.stdout.splitlines() if line.startswith("the paper's method warned: ")]
    # its 2.2-neighbour normals leave the winding number undecided, and the resolution check flags it all
    assert [line[:60] for line in warned] == [
        "the paper's method warned: method 'paper' does not suit this",
        "the paper's method warned: cannot tell whether the cloud enc",
        "the paper's method warned: the cloud is too coarse for its c",
    ]


def test_demo_on_the_bunny(tmp_path):
    out = run("demo", "--bunny", "-o", "bunny.png", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "1839 points" in out.stdout and BUNNY_ATTRIBUTION in out.stdout
    # the picture greys the unreliable points, as heatcurv render does, and says how many
    reliable = int(re.search(r"(\d+) of 1839 points reliable", out.stdout).group(1))
    assert f"front and back; grey: the {1839 - reliable} unreliable point(s)" in out.stdout
    image = read_image(tmp_path / "bunny.png")
    assert image.shape[:2] == (800, 1600) and distinct_colours(image) > 100


def test_the_bunny_ships_with_its_attribution():
    path = bunny_path()
    header = path.read_bytes()[:400].decode("ascii")
    assert f"comment {BUNNY_ATTRIBUTION}\n" in header
    assert "element vertex 1839" in header
    assert (path.parent / "README.md").is_file()
