"""The package's shape: one-way imports, a core free of io/cli/render/surfaces/tiles, short modules, a short API."""

import ast
import importlib
import io
import re
import tokenize
from pathlib import Path

import pytest

import heatcurv

PACKAGE = Path(heatcurv.__file__).parent
#: Packages and modules around the numerical core; the core imports none of them.
OUTER = ("io", "cli", "render", "shading", "view", "surfaces", "data", "tiles")
#: Modules that are the package's facades, not the core.
FACADES = ("__init__", "__main__")
MAX_LINES = 900


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set:
    """Every heatcurv module ``path`` imports, at the top or inside a function."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "heatcurv"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "heatcurv":
                continue
            for alias in node.names:  # `from . import surfaces` imports a module
                candidate = f"{target}.{alias.name}"
                found.add(candidate if candidate in MODULES else target)
    return {m for m in found if m in MODULES and m != name}


FILES = sorted(PACKAGE.rglob("*.py"))
MODULES = {_module_name(p): p for p in FILES}
GRAPH = {name: _imports(path) for name, path in MODULES.items()}


def _is_outer(module: str) -> bool:
    rest = module.split(".")[1:]
    return bool(rest) and rest[0] in OUTER


def _is_core(module: str) -> bool:
    rest = module.split(".")[1:]
    return bool(rest) and not _is_outer(module) and rest[-1] not in FACADES


def test_the_core_imports_nothing_from_outside_it():
    core = [m for m in MODULES if _is_core(m)]
    assert "heatcurv.estimator" in core and "heatcurv._kernels.chordfit" in core
    offenders = {m: sorted(i for i in GRAPH[m] if _is_outer(i)) for m in core}
    assert {m: v for m, v in offenders.items() if v} == {}


def test_no_import_circles():
    # depth-first search for a back edge in the module graph (lazy imports included)
    state, cycles = {}, []

    def visit(m, stack):
        state[m] = "open"
        for dep in sorted(GRAPH[m]):
            if dep.startswith(m + "."):
                continue  # a package importing its own submodules is not a circle
            if state.get(dep) == "open":
                cycles.append(stack[stack.index(dep):] + [dep] if dep in stack else [m, dep])
            elif dep not in state:
                visit(dep, stack + [dep])
        state[m] = "done"

    for m in sorted(GRAPH):
        if m not in state:
            visit(m, [m])
    # the package facade imports its modules; modules importing the facade back are the circles
    real = [c for c in cycles if not any(x == "heatcurv" for x in c)]
    assert real == []


#: The core's subpackages by role, lowest first: each imports only the ones below it (and the basics).
LAYERS = (("geometry",), ("operators",), ("flags", "orient"), ("fits",), ("choice",))
#: What every layer may import: the contract, the threads, the compiled kernels.
BASICS = ("errors", "tuning", "options", "progress", "backend", "_kernels")


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_the_core_subpackages_are_layered_by_role():
    level = {name: i for i, layer in enumerate(LAYERS) for name in layer}
    assert all((PACKAGE / name / "__init__.py").exists() for name in level)
    offenders = []
    for module, deps in GRAPH.items():
        own = _top(module)
        if own not in level:
            continue
        for dep in deps:
            other = _top(dep)
            if other == own or other in BASICS:
                continue
            if other not in level or level[other] >= level[own]:
                offenders.append(f"{module} -> {dep}")
    assert offenders == []


def test_compiled_kernels_never_import_their_callers():
    for name, deps in GRAPH.items():
        if name.startswith("heatcurv._kernels"):
            assert all(d.startswith("heatcurv._kernels") or d == "heatcurv.errors" for d in deps), (name, deps)


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_modules_are_short(path):
    assert len(path.read_text().splitlines()) <= MAX_LINES


def _lines_of_code(source: list, node: ast.FunctionDef) -> int:
    """Lines of a function's body that are neither blank, comments nor its docstring."""
    body = node.body
    docstring = isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) and isinstance(
        body[0].value.value, str)
    start = body[0].end_lineno + 1 if docstring else body[0].lineno
    return sum(1 for line in source[start - 1 : node.end_lineno] if line.strip() and not line.strip().startswith("#"))


def _functions():
    """``(module, name, lines of code, arguments, compiled)`` of every function of the package."""
    for path in FILES:
        text = path.read_text()
        source = text.splitlines()
        for node in ast.walk(ast.parse(text, filename=str(path))):
            if isinstance(node, ast.FunctionDef):
                compiled = any("jit" in ast.unparse(d) for d in node.decorator_list)
                yield _module_name(path), node.name, _lines_of_code(source, node), len(node.args.args), compiled


def test_functions_are_short():
    """At most three functions outside the compiled kernels run over 60 lines of code, none over 70."""
    long = sorted((loc, f"{module}.{name}") for module, name, loc, _, compiled in _functions()
                  if not compiled and loc > 60)
    assert len(long) <= 3 and all(loc <= 70 for loc, _ in long), long


def test_compiled_kernels_are_short_and_bundle_their_arrays():
    """No compiled kernel takes over 14 arguments (arrays that travel together are one tuple) or runs over 120
    lines of code."""
    long = sorted((args, loc, f"{module}.{name}") for module, name, loc, args, compiled in _functions()
                  if compiled and (args > 14 or loc > 120))
    assert not long, long


def test_the_public_api_is_short_and_the_building_blocks_stay_in_their_modules():
    assert sorted(heatcurv.__all__) == [
        "CurvatureResult", "FeatureResult", "HeatcurvError", "HeatcurvWarning", "METHODS", "Options",
        "PointCloudLaplacian", "ScaleTuning", "compute_file", "estimate", "laplacian", "sharp_features", "surfaces",
    ]
    assert all(hasattr(heatcurv, name) for name in heatcurv.__all__)
    # one way to get a Laplacian at the top; the others from their modules
    for module, name in [("geometry.neighbourhood", "ball_neighbourhood"), ("operators.operator", "build_operator"),
                         ("operators.point_laplacian", "point_cloud_laplacian"),
                         ("operators.laplace_beltrami", "laplace_beltrami_matrix"),
                         ("orient.normals", "pca_normals"), ("options", "resolve_options")]:
        assert not hasattr(heatcurv, name), name
        assert callable(getattr(importlib.import_module(f"heatcurv.{module}"), name))


@pytest.mark.parametrize("name", ["pipeline", "baseline", "evaluation", "_deprecation", "testing"])
def test_no_shim_or_test_harness_is_installed(name):
    assert not (PACKAGE / f"{name}.py").exists() and not (PACKAGE / name).exists()


#: History in a comment or docstring: it belongs in git and in docs/, the source says why the code is as it is.
HISTORY = {
    "commit hash": re.compile(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b"),
    "date": re.compile(r"\b(19|20)\d{2}-\d{2}-\d{2}\b"),
    "issue number": re.compile(r"\b(issue|pr|pull request)\s*#?\d+\b|(?<![\w&#])#\d+\b", re.IGNORECASE),
    "measurement log": re.compile(r"\bmeasured(\s*\([^)]*\))?\s*:", re.IGNORECASE),
    "before -> after": re.compile(r"\d\s*(%|s|deg)?\s*->\s*-?\d"),
}


def _comments_and_docstrings(path: Path) -> list:
    """``(line, text)`` of every comment and every module, class and function docstring of ``path``."""
    source = path.read_text()
    found = [(tok.start[0], tok.string) for tok in tokenize.generate_tokens(io.StringIO(source).readline)
             if tok.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(source, filename=str(path))):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc is not None:
                found.append((node.body[0].lineno, doc))
    return found


def _history(text: str) -> list:
    return [f"{kind}: {m.group(0)!r}" for kind, pattern in HISTORY.items() for m in pattern.finditer(text)]


@pytest.mark.parametrize("text, kinds", [
    ("# chosen in commit 3f9a2c1 after a long run", ["commit hash"]),
    ("#: since 2026-11-30 the gate is stricter", ["date"]),
    ('"""The fix of issue 28 (see also issue #12 and #7)."""', ["issue number"] * 3),
    ("#: Measured: torus 0.63, 0.62 and 0.53", ["measurement log"]),
    ("#: Measured (median, random samples): 0.4", ["measurement log"]),
    ("#: the torus went from 5.34 -> 5.68 %", ["before -> after"]),
    ("#: a straight border's ball is a half disc, whose centroid lies 4R/(3 pi) inside", []),
    ('"""``x -> x + w x x``, 1e-7 of the diagonal, 0123456789, 4R/(3 pi)."""', []),
])
def test_the_history_check_finds_history_and_nothing_else(text, kinds):
    assert [found.split(":")[0] for found in _history(text)] == kinds


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_comments_explain_the_code_not_its_history(path):
    # no commit hashes, dates, issue numbers or measurement logs: the measurements are in docs/
    # (docs/how_it_works.md, thresholds), the history in git
    offenders = [f"line {line}: {found}" for line, text in _comments_and_docstrings(path) for found in _history(text)]
    assert offenders == []
