"""Cross-references in the docstrings checked against the code, and whole one-line summaries.

A small Sphinx extension.

With ``-n`` (nitpicky) every unresolved reference warns. A reference that the
API pages document links there. Docstrings also name objects that are not in
a module's ``__all__`` (private helpers, submodules of a package documented
as a whole): such a reference is resolved here, first to the documented
object of the same name higher up its package (``notchfit.analysis.diagnosis.noise.paired_z``
-> ``notchfit.analysis.diagnosis.paired_z``), else shown as code when the name exists
in the package's code. A name that exists nowhere still fails the build.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

from sphinx import addnodes
from sphinx.ext import autosummary
from sphinx.transforms.post_transforms import SphinxPostTransform

PACKAGE = "notchfit"


def _lookup(path: str):
    """The object at dotted ``path`` (a module, or attributes below one), or raise LookupError."""
    parts = path.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for name in parts[i:]:
            fields = getattr(obj, "__dataclass_fields__", {})
            if hasattr(obj, name):
                obj = getattr(obj, name)
            elif name in fields or name in getattr(obj, "__annotations__", {}):
                obj = None
            else:
                raise LookupError(path)
        return obj
    raise LookupError(path)


def _exists(target: str, module: str | None, cls: str | None) -> bool:
    """Whether ``target`` names an object of the package's code from the context of ``module``/``cls``."""
    target = target.lstrip("~.")
    bases = [""]
    if module:
        parts = module.split(".")
        bases += [".".join(parts[:i]) + "." for i in range(len(parts), 0, -1)]
        if cls:
            bases.insert(1, f"{module}.{cls}.")
    for base in bases:
        try:
            _lookup(base + target)
            return True
        except LookupError:
            pass
    head = target.split(".")[0]
    for name, mod in list(sys.modules.items()):
        if name.startswith(PACKAGE + ".") and mod is not None and hasattr(mod, head):
            try:
                _lookup(f"{name}.{target}")
                return True
            except LookupError:
                continue
    return False


def _documented(domain, target: str, reftype: str) -> str | None:
    """The documented name for ``target``: the same last name under one of its parent packages
    (a submodule: its package)."""
    modules = getattr(domain, "modules", {})
    parts = target.split(".")
    if reftype == "mod":
        for i in range(len(parts) - 1, 0, -1):
            if ".".join(parts[:i]) in modules:
                return ".".join(parts[:i])
        return None
    for k in range(len(parts) - 2, 0, -1):
        cand = ".".join(parts[:k] + parts[-1:])
        if cand in domain.objects:
            return cand
    return None


def missing_reference(app, env, node, contnode):
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    module, cls = node.get("py:module"), node.get("py:class")
    domain = env.get_domain("py")
    if target.startswith(PACKAGE + "."):
        doc = _documented(domain, target, node["reftype"])
        if doc is not None:
            return domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], doc, node, contnode)
    if _exists(target, module, cls):
        return contnode
    return None


#: Repository files that the Markdown pages link to and that the site holds as a page of its own.
REPOSITORY_PAGES = {"CONVENTIONS": "conventions", "CHANGELOG": "changelog"}


class RepositoryPageLinks(SphinxPostTransform):
    """A page's link to a repository file the site includes (``../CONVENTIONS.md``) goes to its page."""

    default_priority = 8        # before MyST resolves its links (9)

    def run(self, **kwargs) -> None:
        root = Path(self.env.srcdir).parent
        for node in self.document.findall(addnodes.pending_xref):
            if node.get("reftype") != "myst" or node.get("refdomain") != "doc":
                continue
            target = str(node["reftarget"])
            for name, page in REPOSITORY_PAGES.items():
                if target in (str(root / name), f"../{name}", name):
                    node["reftarget"] = page


#: Abbreviations the docstrings use before a number: their period ends no sentence.
ABBREVIATIONS = ("Sec.", "Secs.", "Eq.", "Eqs.", "Fig.", "Figs.", "e.g.", "i.e.", "cf.", "vs.")


def _first_sentence(lines) -> str:
    """The first sentence of a docstring's first paragraph; a period inside parentheses
    (``(Sec. IV-B)``) or after an abbreviation (``Sec. IV-B``) does not end it."""
    para = []
    for line in lines:
        if not line.strip():
            if para:
                break
            continue
        para.append(line.strip())
    text, depth = " ".join(para), 0
    for i, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if ch == "." and depth <= 0 and (i + 1 == len(text) or text[i + 1].isspace()) \
                and not text[:i + 1].endswith(ABBREVIATIONS):
            return text[:i + 1]
    return text


_autosummary_summary = autosummary.extract_summary


def extract_summary(doc, settings) -> str:
    """autosummary's one-line summary, unless it stops at a period inside parentheses
    (``Backbone kinematics (Sec.``) or after an abbreviation: then the whole first sentence."""
    summary = _autosummary_summary(doc, settings)
    if summary.count("(") > summary.count(")") or summary.endswith(ABBREVIATIONS):
        return _first_sentence(doc)
    return summary


def setup(app):
    autosummary.extract_summary = extract_summary
    app.connect("missing-reference", missing_reference)
    app.add_post_transform(RepositoryPageLinks)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
