"""One record per cause (notchfit.analysis.causes): complete, and the only table of causes in the package."""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest

from notchfit.analysis.causes import CAUSES, FIGURE_KINDS, REGISTRY, REQUIREMENTS, Cause, ScoreTerm
from notchfit.analysis.estimation import ParamSpec
from notchfit.figures.diagnosis import VIEWS
from notchfit.studies.recipes import list_recipes, load_recipe

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "notchfit"
#: Verdicts and model names that are not causes.
NOT_CAUSES = {"none", "unexplained", "baseline"}


def measured_signatures() -> set[str]:
    """The signature names the diagnosis computes (the first argument of every ``Signature(...)``)."""
    tree = ast.parse((PACKAGE / "analysis" / "diagnosis" / "signatures.py").read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "Signature" and node.args:
            a = node.args[0]
            if isinstance(a, ast.Constant) and isinstance(a.value, str):
                names.add(a.value)
        if isinstance(node, ast.Tuple) and node.elts and isinstance(node.elts[0], ast.Constant) \
                and str(node.elts[0].value).startswith("b_"):
            names.add(node.elts[0].value)         # the slope signatures are named in a loop
    return names


def problems(c: Cause, signatures: set[str]) -> list[str]:
    """What a record lacks or gets wrong (empty: complete)."""
    out = []
    if not re.fullmatch(r"[a-z]+(_[a-z]+)+", c.id):
        out.append("id is not a snake_case cause id")
    if not c.params or not all(isinstance(s, ParamSpec) for s in c.params):
        out.append("no fitted parameters")
    if not c.laws or not all(law and all(isinstance(k, str) for k in law) for law in c.laws):
        out.append("no recipe law")
    if len(c.label) < 20:
        out.append("no label")
    if not c.explanation.startswith("Physically: "):
        out.append("no explanation")
    if c.figure not in FIGURE_KINDS or c.figure not in VIEWS:
        out.append(f"figure kind {c.figure!r} has no view")
    for name, ideal, words in c.targets:
        if name not in signatures or not words or not isinstance(ideal, float):
            out.append(f"target {name!r} is not a measured signature")
    if not c.targets and not c.corrects_points:
        out.append("no target signature")
    if not c.signature or not all(isinstance(t, ScoreTerm) and t.signature in signatures and t.weight > 0
                                  for t in c.signature):
        out.append("no signature score over measured signatures")
    if not c.reason:
        out.append("no reason")
    if set(c.requires) - set(REQUIREMENTS) or not all(c.requires.values()):
        out.append("unknown requirement or requirement without reason")
    return out


@pytest.mark.parametrize("cid", CAUSES)
def test_every_record_is_complete(cid):
    assert problems(REGISTRY[cid], measured_signatures()) == []


def test_an_incomplete_record_is_caught():
    """The completeness check fails for a record with a field left empty (each one in turn)."""
    sigs = measured_signatures()
    good = REGISTRY["joint_hysteresis"]
    for field, empty in (("params", ()), ("laws", ()), ("label", ""), ("explanation", ""), ("figure", "pie"),
                         ("targets", ()), ("signature", ()), ("reason", ""), ("requires", {"wings": "x"})):
        assert problems(dataclasses.replace(good, **{field: empty}), sigs), field


def test_records_agree_with_each_other():
    """Ties are broken by distinct ranks; every fitted parameter name belongs to one cause only; a law's
    fields are each the cause's own."""
    assert sorted(c.rank_tie for c in REGISTRY.values()) == list(range(len(CAUSES)))
    names = [s.name for c in REGISTRY.values() for s in c.params]
    assert len(names) == len(set(names))
    fields = [k for c in REGISTRY.values() for k in {k for law in c.laws for k in law}]
    assert len(fields) == len(set(fields))


def test_docs_and_recipes_name_registry_causes_only():
    """The cause table of docs/data-formats.md lists exactly the registry; shipped recipes hide known causes."""
    doc = (ROOT / "docs" / "data-formats.md").read_text(encoding="utf-8")
    table = doc[doc.index("Effect fields by cause:"):]
    table = table[:table.index("\n\n", table.index("| cause |"))]
    assert re.findall(r"^\| `([a-z_]+)` \|", table, flags=re.M) == list(CAUSES)
    for name in list_recipes():
        assert set(load_recipe(name).causes) <= set(CAUSES), name


def _cause_tables(tree) -> list[int]:
    """Lines of dict literals keyed by cause ids (two or more: one may be a parameter of the same name,
    ``stiffness_gradient``)."""
    return [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Dict)
            and sum(isinstance(k, ast.Constant) and k.value in REGISTRY for k in n.keys) >= 2]


def _named_causes(tree) -> list[tuple[int, str]]:
    """String constants compared with something named like a cause (``c.cause != "x"``, ``"x" in causes``)."""
    out = []
    for n in ast.walk(tree):
        if not isinstance(n, ast.Compare):
            continue
        parts = [n.left, *n.comparators]
        if not any("cause" in ast.unparse(p) for p in parts):
            continue
        for p in parts:
            for c in ([p] if isinstance(p, ast.Constant) else getattr(p, "elts", [])):
                if isinstance(c, ast.Constant) and isinstance(c.value, str):
                    out.append((n.lineno, c.value))
    return out


def test_no_module_keeps_its_own_cause_table_or_names_an_unknown_cause():
    """Only notchfit/analysis/causes.py maps cause ids to anything; every cause a module compares with is known."""
    tables, unknown = [], []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "causes.py" and path.parent == PACKAGE / "analysis":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        rel = path.relative_to(ROOT)
        tables += [f"{rel}:{line}" for line in _cause_tables(tree)]
        unknown += [f"{rel}:{line}: {v!r}" for line, v in _named_causes(tree)
                    if v not in REGISTRY and v not in NOT_CAUSES and re.fullmatch(r"[a-z]+(_[a-z]+)+", v)]
    assert not tables, "tables keyed by cause ids outside notchfit/analysis/causes.py: " + ", ".join(tables)
    assert not unknown, "causes the registry lacks: " + ", ".join(unknown)
