"""The package's structure: no import cycles, layers that point one way, short functions.

These are the rules of docs/architecture.md, checked on the source: every
``import`` statement (module level and inside functions) of every module of
``notchfit`` is an edge of the import graph.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "notchfit"

#: physics: pure models over numpy arrays; they read and write no files.
PHYSICS = tuple(f"physics.{m}" for m in ("geometry", "kinematics", "notches", "cables", "springs", "statics",
                                          "friction", "_friction_kernels", "_hysteresis_kernels", "_spring_kernels",
                                          "friction_params", "predictor", "shapes", "section", "protocols")) + \
    ("units", "validation", "paper", "polygon")
#: analysis: returns objects, writes nothing.
ANALYSIS = ("analysis",)
#: the estimation core, one floor below both engines (identify, diagnosis).
ESTIMATION = ("analysis.estimation",)
ENGINES = ("analysis.identify", "analysis.diagnosis")
#: vision: cameras, images, rendering and detection, below the file I/O (they read and write no files).
VISION = ("vision", "imaging")
#: what vision and the estimation core must not import: the file I/O and everything above it.
ABOVE_ANALYSIS = ("notchfit.io", "notchfit.batch", "notchfit.commands", "notchfit.cli", "notchfit.figures",
                  "notchfit.report", "notchfit.studies.synth", "notchfit.studies.recipes")
MAX_MODULE_LINES = 800
#: modules that may exceed the module length limit: the numba kernels of the friction solvers
#: (each time loop kept whole for the compiler, with the helpers it inlines).
LONG_MODULES_ALLOWED = ("_friction_kernels",)
#: modules whose functions may exceed the length limit: the numba kernels (one
#: time loop each, kept whole for the compiler).
LONG_FUNCTIONS_ALLOWED = ("_friction_kernels",)
MAX_FUNCTION_LINES = 100


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """notchfit modules imported anywhere in ``path`` (resolved to module names)."""
    is_pkg = path.name == "__init__.py"
    here = name if is_pkg else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [f"{mod}.{a.name}" for a in node.names] + [mod]
        for t in targets:
            # the longest prefix that is a module of the package
            parts = t.split(".")
            for k in range(len(parts), 0, -1):
                cand = ".".join(parts[:k])
                if cand in modules:
                    # a module's own package (and its parents) is imported before it anyway
                    if cand != name and not name.startswith(cand + "."):
                        out.add(cand)
                    break
    return out


def import_graph() -> dict[str, set[str]]:
    modules = all_modules()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle (a list of modules, first == last), or None.

    A package importing its own submodules (``notchfit.io`` -> ``notchfit.io.tables``)
    is not a cycle unless a submodule imports the package's __init__ back.
    """
    WHITE, GREY, BLACK = 0, 1, 2
    colour = {m: WHITE for m in graph}
    stack: list[str] = []

    def visit(m):
        colour[m] = GREY
        stack.append(m)
        for n in sorted(graph[m]):
            if colour[n] == GREY:
                return stack[stack.index(n):] + [n]
            if colour[n] == WHITE:
                c = visit(n)
                if c:
                    return c
        stack.pop()
        colour[m] = BLACK
        return None

    for m in sorted(graph):
        if colour[m] == WHITE:
            c = visit(m)
            if c:
                return c
    return None


def test_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_import_resolution_of_relative_imports():
    modules = all_modules()
    graph = import_graph()
    assert "notchfit.physics.geometry" in graph["notchfit.physics.kinematics"]
    assert set(graph) == set(modules)


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def _layer_members(names):
    graph = import_graph()
    return {m: deps for m, deps in graph.items()
            if any(m == f"notchfit.{n}" or m.startswith(f"notchfit.{n}.") for n in names)}


@pytest.mark.parametrize("module", PHYSICS)
def test_physics_imports_no_file_io_and_nothing_above_it(module):
    graph = import_graph()
    deps = graph[f"notchfit.{module}"]
    above = ("notchfit.io", "notchfit.commands", "notchfit.cli", "notchfit.figures", "notchfit.report",
             "notchfit.analysis.diagnosis", "notchfit.analysis.fitting", "notchfit.studies.synth", "notchfit.studies.recipes", "notchfit.batch")
    bad = sorted(d for d in deps if any(d == a or d.startswith(a + ".") for a in above))
    assert not bad, f"notchfit.{module} (physics) imports {bad}"


def test_analysis_writes_nothing():
    """fitting and diagnosis import no I/O, figures, commands or CLI module."""
    above = ("notchfit.io", "notchfit.commands", "notchfit.cli", "notchfit.figures", "notchfit.report")
    for m, deps in _layer_members(ANALYSIS).items():
        bad = sorted(d for d in deps if any(d == a or d.startswith(a + ".") for a in above))
        assert not bad, f"{m} (analysis) imports {bad}"


def _bad(deps, forbidden) -> list[str]:
    return sorted(d for d in deps if any(d == a or d.startswith(a + ".") for a in forbidden))


#: the one engine edge allowed: the diagnosis's baseline of a real tube is identify's calibrated model,
#: whose per-tube unknowns it takes from ``analysis.identify`` (identify imports no diagnosis).
ENGINE_EDGES = {"analysis.diagnosis": ("analysis.identify",)}


def test_estimation_sits_below_both_engines():
    """The estimation core imports neither engine nor anything above the analysis; both engines build on it;
    identify imports no diagnosis, and the diagnosis only identify's problem and specs."""
    engines = tuple(f"notchfit.{e}" for e in ENGINES)
    for m, deps in _layer_members(ESTIMATION).items():
        bad = _bad(deps, engines + ABOVE_ANALYSIS + ("notchfit.analysis.causes", "notchfit.analysis.comparison"))
        assert not bad, f"{m} (estimation core) imports {bad}"
    for engine in ENGINES:
        members = _layer_members((engine,))
        uses = {d for deps in members.values() for d in deps if d.startswith("notchfit.analysis.estimation")}
        assert uses, f"notchfit.{engine} does not build on notchfit.analysis.estimation"
        other = tuple(f"notchfit.{e}" for e in ENGINES if e != engine and e not in ENGINE_EDGES.get(engine, ()))
        for m, deps in members.items():
            assert not _bad(deps, other), f"{m} imports the other engine: {_bad(deps, other)}"
        allowed = tuple(f"notchfit.{e}.{sub}" for e in ENGINE_EDGES.get(engine, ()) for sub in ("problem", "specs"))
        for m, deps in members.items():
            up = [d for d in _bad(deps, tuple(f"notchfit.{e}" for e in ENGINE_EDGES.get(engine, ())))
                  if d not in allowed and d not in tuple(f"notchfit.{e}" for e in ENGINE_EDGES.get(engine, ()))]
            assert not up, f"{m} imports more of identify than its problem and specs: {up}"


def test_vision_sits_below_file_io():
    """Cameras, rendering and detection import no file I/O, batch runner or anything above them."""
    for m, deps in _layer_members(VISION).items():
        bad = _bad(deps, ABOVE_ANALYSIS)
        assert not bad, f"{m} (vision) imports {bad}"


def test_layer_checks_catch_a_violation():
    """The layer helpers see a forbidden edge (a check that could not fail would prove nothing)."""
    assert _bad({"notchfit.io.outputs", "notchfit.physics.geometry"}, ABOVE_ANALYSIS) == ["notchfit.io.outputs"]
    assert _bad({"notchfit.iota"}, ("notchfit.io",)) == []


def test_no_module_longer_than_the_limit():
    long = [f"{name}: {n} lines" for name, path in all_modules().items()
            if name.rpartition(".")[2] not in LONG_MODULES_ALLOWED
            and (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES]
    assert not long, "modules over the limit: " + "; ".join(long)


def test_commands_do_not_import_the_cli():
    for m, deps in import_graph().items():
        if m.startswith("notchfit.commands"):
            assert "notchfit.cli" not in deps, f"{m} imports notchfit.cli (the CLI imports the commands)"


def test_no_function_longer_than_the_limit():
    long = []
    for name, path in all_modules().items():
        if name.rpartition(".")[2] in LONG_FUNCTIONS_ALLOWED:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{name}.{node.name}: {n} lines")
    assert not long, "functions over the limit: " + "; ".join(long)


#: the detector's stages pass records, not long argument lists: the most parameters without a default
MAX_DETECTOR_PARAMETERS = 9


def required_parameters(node: ast.FunctionDef) -> int:
    """Parameters of a function definition without a default (positional and keyword-only)."""
    a = node.args
    return len(a.posonlyargs) + len(a.args) - len(a.defaults) + sum(d is None for d in a.kw_defaults)


def test_required_parameters_counts_only_those_without_a_default():
    node = ast.parse("def f(a, b=1, *c, d, e=2, **g): pass").body[0]
    assert required_parameters(node) == 2


def wide_functions(tree: ast.AST, limit: int) -> list[str]:
    """The functions of ``tree`` with more than ``limit`` parameters without a default (``name: n parameters``)."""
    return [f"{node.name}: {n} parameters" for node in ast.walk(tree)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and (n := required_parameters(node)) > limit]


def test_wide_functions_finds_those_past_the_limit():
    tree = ast.parse("def f(a, b, c): pass\ndef g(a, b=1, *, c=2): pass\nclass K:\n    def h(self, a, *, b): pass")
    assert wide_functions(tree, 2) == ["f: 3 parameters", "h: 3 parameters"]


def _wide_in(prefixes, limit) -> list[str]:
    """:func:`wide_functions` of every module whose name starts with one of ``prefixes``."""
    return [f"{name}.{w}" for name, path in all_modules().items() if name.startswith(prefixes)
            for w in wide_functions(ast.parse(path.read_text(encoding="utf-8")), limit)]


def test_no_detector_function_with_ten_or_more_parameters():
    wide = _wide_in(("notchfit.vision.detection",), MAX_DETECTOR_PARAMETERS)
    assert not wide, "detector functions with too many parameters (carry them in a record): " + "; ".join(wide)


#: modules whose wide functions were narrowed to records (the numba kernels included: they take named
#: tuples made in compiled code, or plain tuples of arrays, which numba reads as fast as separate arguments)
NARROWED_MODULES = ("notchfit.analysis.fitting.lm", "notchfit.analysis.identify.problem",
                    "notchfit.analysis.identify.study", "notchfit.commands._resumable", "notchfit.physics.predictor",
                    "notchfit.physics.notches", "notchfit.studies.synth", "notchfit.studies.stock")
#: the most parameters without a default in those modules
MAX_NARROWED_PARAMETERS = 8
#: public signatures kept for their callers: the compiled point kernel of the API reference (its work
#: arrays are the caller's; notchfit itself calls the narrow one)
WIDE_PUBLIC_ALLOWED = ("notchfit.physics.notches.points_kernel: 11 parameters",)


def test_no_narrowed_function_grows_past_eight_parameters():
    modules = all_modules()
    wide = [f"{m}.{w}" for m in NARROWED_MODULES
            for w in wide_functions(ast.parse(modules[m].read_text(encoding="utf-8")), MAX_NARROWED_PARAMETERS)]
    wide = [w for w in wide if w not in WIDE_PUBLIC_ALLOWED]
    assert not wide, "functions with too many parameters (name the concept in a record): " + "; ".join(wide)


#: how a reference to the contracts folder beside the repository would be spelled (built from
#: parts so that this test does not contain what it looks for)
OUTSIDE_MARKERS = ("../" + "shared", "shared/" + "spec")


def test_nothing_points_outside_the_repository():
    """The package stands alone: no reference to a folder beside the repository."""
    root = PACKAGE.parent
    hits = []
    for path in [*PACKAGE.rglob("*.py"), root / "README.md", root / "CONVENTIONS.md", root / "pyproject.toml"]:
        text = path.read_text(encoding="utf-8")
        if any(marker in text for marker in OUTSIDE_MARKERS):
            hits.append(str(path.relative_to(root)))
    assert not hits, f"references to the folder beside the repository in {hits}"
