"""README.md and the user guide in docs/: what they show is what the code does, and every link leads somewhere.

The accuracy table is the output of ``heatcurv demo`` (the paper's torus, 20 000 random points, seed 0).
Its ``default`` row is recomputed here and must equal each printed value to the printed digits, read
from README.md itself, so the README cannot go stale when the estimator changes. The ``paper`` row
takes 20-60 s on 2 cores and is not recomputed: the README names the machine that printed it.

The README's Python example runs and must print the text block under it, the example of
docs/getting_started.md runs on the shipped bunny scan, and every other ```python block of docs/ runs
(in a temporary directory) unless ``NOT_RUN`` says why it cannot; the command-line sessions
(```console blocks of README.md and docs/cli.md) run on the shipped bunny scan and must print what
they show, but for the time an estimate took. Every relative link of README.md and docs/*.md must
lead to a file (and a heading, for a ``#`` anchor), so must CHANGELOG.md's, mkdocs.yml's navigation must
list every page, and ``mkdocs build --strict`` must pass.
"""

import contextlib
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import heatcurv
import heatcurv.data
from heatcurv.surfaces.accuracy import compare

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
CHANGELOG = ROOT / "CHANGELOG.md"
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
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
    # docs/how_it_works.md: "eq 2.6 measures about half the spacing sqrt(area / n) of a random cloud" (0.50 at
    # 20 000 random points of the unit sphere, 0.96 on a Fibonacci sphere, whose points are evenly spaced)
    from heatcurv.geometry.spacing import global_spacing

    step = np.sqrt(4 * np.pi / 20000)
    random = global_spacing(heatcurv.surfaces.Sphere().sample(20000, "random", seed=1).points) / step
    regular = global_spacing(heatcurv.surfaces.Sphere().sample(20000, "fibonacci").points) / step
    assert 0.45 < random < 0.55 and 0.9 < regular < 1.0


def _blocks(text, language):
    """The contents of the fenced code blocks of ``language`` in Markdown ``text``, in order."""
    return re.findall(rf"^```{language}\n(.*?)^```$", text, flags=re.S | re.M)


def test_readme_is_short():
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 150


def test_readme_python_example_prints_what_the_readme_shows():
    text = README.read_text(encoding="utf-8")
    code, printed = _blocks(text, "python")[0], _blocks(text, "text")[0]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), {"__name__": "readme"})
    assert out.getvalue() == printed


def test_getting_started_example_runs():
    code = _blocks((DOCS / "getting_started.md").read_text(encoding="utf-8"), "python")[0]
    scope = {"__name__": "getting_started"}
    exec(compile(code, "getting_started.md", "exec"), scope)
    res, feat, lap = scope["res"], scope["feat"], scope["lap"]
    n = len(scope["points"])
    assert n == 1839 and res.mean.shape == (n,) and res.d1.shape == (n, 3) and feat.mask.shape == (n,)
    assert scope["L"].shape == (n, n) and lap.n == n


def _examples(path):
    """The ```python blocks of a Markdown file, indented ones (inside a list) included, dedented."""
    found = re.findall(r"^( *)```python\n(.*?)^\1```$", path.read_text(encoding="utf-8"), flags=re.S | re.M)
    return [textwrap.dedent(code) for _, code in found]


# (page, block number) of the docs' Python examples that the tests do not run, why, and a string the block
# must contain for the reason to hold (so that an edited block is looked at again)
NOT_RUN = {
    ("tiles.md", 0): ("it computes a cloud larger than memory, 'big.laz'; tests/tiles/ run compute_file on small "
                      "clouds in tiles", "big.laz"),
    ("tiles.md", 1): ("it needs a SLURM cluster (dask_jobqueue); tests/tiles/ run the Dask schedulers on a local "
                      "cluster", "SLURMCluster"),
    ("tiles.md", 2): ("it needs a Kubernetes cluster with the Dask operator (dask_kubernetes); tests/tiles/ run the "
                      "Dask schedulers on a local cluster", "KubeCluster"),
}
# run by a test of their own, which also checks what they return
RUN_ELSEWHERE = {("getting_started.md", 0)}


def _bunny_points():
    from heatcurv.io import read_points

    return read_points(heatcurv.data.bunny_path()).points


def _check_laplacian(scope):
    n = len(scope["points"])
    values, u = scope["values"], scope["u"]
    assert values.shape == (20,) and np.all(np.diff(values) >= -1e-9) and abs(values[0]) < 1e-6
    assert scope["vectors"].shape == (n, 20) and scope["K"].shape == (n, 3)
    # the heat flow spreads the unit of heat from its point and keeps the total, sum_i A_i u_i
    area, u0 = scope["lap"].area, scope["u0"]
    assert u.shape == (n,) and u.max() < 0.5 and abs(area @ u - area @ u0) <= 1e-9 * (area @ u0)


def _check_viewer(scope):
    assert scope["view"].shown == 20000 and Path("torus.html").is_file()


def _check_plan(scope):
    # the plan's line, as the page prints it under the example
    page = (DOCS / "getting_started.md").read_text(encoding="utf-8")
    shown = re.search(r'print\(plan\.describe\(\)\)\n```\n\n```text\n(.*?)\n```', page).group(1)
    assert scope["plan"].describe() == shown


# a fragment that names data it does not define is run with that data; some examples' results are checked
SCOPES = {("index.md", 0): lambda: {"points": _bunny_points()}}
CHECKS = {("laplacian.md", 0): _check_laplacian, ("viewer.md", 0): _check_viewer,
          ("getting_started.md", 1): _check_plan}
DOC_EXAMPLES = [(page.name, i, code) for page in PAGES for i, code in enumerate(_examples(page))]


@pytest.mark.parametrize("name, number, code", [
    pytest.param(name, number, code, id=f"{name}-{number}") for name, number, code in DOC_EXAMPLES
    if (name, number) not in NOT_RUN and (name, number) not in RUN_ELSEWHERE])
def test_docs_python_examples_run(name, number, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # examples that write a file write it here
    scope = {"__name__": f"docs_{name}", **SCOPES.get((name, number), dict)()}
    exec(compile(code, f"docs/{name}", "exec"), scope)
    if (name, number) in CHECKS:
        CHECKS[name, number](scope)


def test_docs_examples_not_run_are_named_with_their_reason():
    blocks = {(name, number): code for name, number, code in DOC_EXAMPLES}
    for key, (reason, marker) in NOT_RUN.items():
        assert key in blocks, f"NOT_RUN names {key}, which is not a python block of docs/"
        assert reason and marker in blocks[key], f"{key} no longer contains {marker!r}: run it or say why not"
    assert RUN_ELSEWHERE <= set(blocks)
    assert len(DOC_EXAMPLES) >= 5


def _sessions(path):
    """``(command, printed lines)`` of every ``$ heatcurv ...`` line of the file's console blocks."""
    sessions = []
    for block in _blocks(path.read_text(encoding="utf-8"), "console"):
        for line in block.splitlines():
            if line.startswith("$ "):
                sessions.append((line[2:], []))
            else:
                sessions[-1][1].append(line)
    return sessions


def _timeless(line):
    """A line of a command's output with the time it took replaced, the one part that changes run to run."""
    return re.sub(r" in \d+(\.\d+)? s ", " in ... s ", line)


@pytest.mark.parametrize("page", [README, DOCS / "cli.md"], ids=lambda p: p.name)
def test_command_line_sessions_print_what_the_page_shows(page, tmp_path):
    # every command must succeed; a command shown with output must print exactly that output (stdout;
    # stderr carries the one-time compile notice of a cold numba cache), a command shown without none
    sessions = _sessions(page)
    assert any(shown for _, shown in sessions), f"no command of {page.name} shows its output"
    shutil.copy(heatcurv.data.bunny_path(), tmp_path)
    for command, shown in sessions:
        words = shlex.split(command)
        assert words[0] == "heatcurv", command
        out = subprocess.run([sys.executable, "-m", "heatcurv", *words[1:]], cwd=tmp_path, capture_output=True,
                             text=True, timeout=300)
        assert out.returncode == 0, (command, out.stderr)
        if shown:
            assert [_timeless(line) for line in out.stdout.splitlines()] == [_timeless(line) for line in shown], command


def _slug(heading):
    """The anchor of a Markdown heading, as GitHub and mkdocs's table of contents make it."""
    text = re.sub(r"[^\w\s-]", "", heading.strip().lower())
    return re.sub(r"\s+", "-", text)


def _links(path):
    """The relative link targets of a Markdown file, code spans and code blocks left out."""
    text = re.sub(r"^```.*?^```$", "", path.read_text(encoding="utf-8"), flags=re.S | re.M)
    text = re.sub(r"`[^`\n]*`", "", text)
    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    return [t for t in targets if not re.match(r"[a-z]+:", t)]


@pytest.mark.parametrize("page", [README, CHANGELOG, *PAGES], ids=lambda p: p.name)
def test_every_relative_link_leads_to_a_file_and_heading(page):
    links = _links(page)
    for link in links:
        target, _, anchor = link.partition("#")
        resolved = (page.parent / target).resolve() if target else page
        assert resolved.exists(), f"{page.name} links to {link}, which is not in the repository"
        assert ROOT in resolved.parents or resolved == ROOT, f"{page.name} links outside the repository: {link}"
        if anchor:
            headings = re.findall(r"^#+ (.*)$", resolved.read_text(encoding="utf-8"), flags=re.M)
            assert anchor in {_slug(h) for h in headings}, f"{page.name} links to {link}: no such heading"


def test_the_changelog_is_in_the_site():
    # MkDocs builds docs/ only: the changelog lives there, the repository's root points to it
    assert "](docs/changelog.md)" in CHANGELOG.read_text(encoding="utf-8")
    text = (DOCS / "changelog.md").read_text(encoding="utf-8")
    assert "## [Unreleased]" in text and all(f"\n### {group}\n" in text for group in ("Added", "Changed", "Fixed"))


def test_the_site_lists_every_page():
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    listed = re.findall(r"^\s*- (?:[^:]+: )?(\S+\.md)\s*$", config, flags=re.M)
    assert sorted(listed) == sorted(page.name for page in PAGES)


def test_the_site_builds_with_no_warning(tmp_path):
    # --strict turns every warning (a broken link or anchor, a page missing from the navigation) into a failure
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
                          "-d", str(tmp_path / "site")], capture_output=True, text=True, timeout=120, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "site" / "getting_started" / "index.html").is_file()
    # the API reference is rendered from the docstrings, its Sphinx roles as plain code
    api = (tmp_path / "site" / "api" / "index.html").read_text(encoding="utf-8")
    assert "Normals, mean, Gaussian and principal curvatures" in api and ":func:" not in api
