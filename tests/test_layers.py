"""The package's folders are its layers, and imports point down (docs/architecture.md).

Every module of ``notchfit`` belongs to one layer, read from its folder; an
import (module level or inside a function) may name a module of its own layer
or of a layer below, never one above. The package root holds the primitives
only, so a module added at the root of the package by mistake fails here.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "notchfit"

#: the layers from the bottom up, each with the dotted prefixes of its modules
LAYERS = (
    ("primitives", ("notchfit.units", "notchfit.validation", "notchfit.paper", "notchfit.polygon",
                    "notchfit.imaging", "notchfit.progress", "notchfit.batch", "notchfit._version",
                    "notchfit._moved")),
    ("physics", ("notchfit.physics",)),
    ("vision", ("notchfit.vision",)),
    ("analysis", ("notchfit.analysis",)),
    ("io", ("notchfit.io",)),
    ("studies", ("notchfit.studies",)),
    ("presentation", ("notchfit.figures", "notchfit.report", "notchfit.review")),
    ("commands", ("notchfit.commands", "notchfit.cli", "notchfit.__main__")),
)
#: the package's own __init__ re-exports a few names from below; it is nobody's dependency
EXEMPT = {"notchfit"}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def layer_of(name: str) -> int | None:
    for rank, (_, prefixes) in enumerate(LAYERS):
        if any(name == p or name.startswith(p + ".") for p in prefixes):
            return rank
    return None


def imports_of(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """notchfit modules that ``name`` imports (relative imports resolved; ``from X import sub`` = X.sub)."""
    is_pkg = path.name == "__init__.py"
    here = name.split(".") if is_pkg else name.split(".")[:-1]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("notchfit")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if not mod.startswith("notchfit"):
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                out.add(sub if sub in known else mod)
    return {m for m in out if m in known or any(k.startswith(m + ".") for k in known)}


def test_every_module_has_a_layer():
    orphans = sorted(m for m in modules() if m not in EXEMPT and layer_of(m) is None)
    assert not orphans, f"modules outside every layer (put them in a layer folder): {orphans}"


def test_imports_point_down():
    known = modules()
    bad = []
    for name, path in known.items():
        if name in EXEMPT:
            continue
        mine = layer_of(name)
        for dep in imports_of(name, path, known):
            theirs = layer_of(dep)
            if dep not in EXEMPT and theirs is not None and mine is not None and theirs > mine:
                bad.append(f"{name} ({LAYERS[mine][0]}) imports {dep} ({LAYERS[theirs][0]})")
    assert not bad, "imports that point up:\n" + "\n".join(bad)


def test_the_package_root_holds_primitives_only():
    root = sorted(p.stem for p in PACKAGE.glob("*.py") if p.stem not in ("__init__", "__main__", "cli"))
    primitives = {p.rsplit(".", 1)[1] for p in LAYERS[0][1]}
    assert set(root) <= primitives, f"modules at the package root that are not primitives: {set(root) - primitives}"


def test_old_names_import_the_new_modules_with_a_warning():
    """Scripts written for the flat layout keep working and are told the new name."""
    import importlib
    import sys
    import warnings

    sys.modules.pop("notchfit.kinematics", None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = importlib.import_module("notchfit.kinematics")
    new = importlib.import_module("notchfit.physics.kinematics")
    assert old is new
    assert any("notchfit.physics.kinematics" in str(w.message) for w in caught)
