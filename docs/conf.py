"""Sphinx configuration of the notchfit documentation site.

Build it from the repository's folder (``pip install -e ".[docs]"`` first)::

    python -m sphinx -W --keep-going -n -b html docs docs/_build/html

The API reference is generated from the docstrings (autodoc, autosummary,
numpydoc); the Markdown pages are read by MyST; the gallery runs the scripts
in ``examples/`` (sphinx-gallery) and embeds their figures.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

import notchfit  # noqa: E402

project = "notchfit"
author = "the notchfit developers"
copyright = "2026, the notchfit developers"
version = release = notchfit.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "sphinx_design",
    "notchfit_xref",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
highlight_language = "text"         # a code block without a language is shown as written
templates_path = ["_templates"]
exclude_patterns = ["_build", "_templates", "auto_examples/*.ipynb", "auto_examples/*.py",
                    "auto_examples/*.zip", "auto_examples/*.md5", "auto_examples/*.codeobj.json",
                    "sg_execution_times.rst"]

# --- MyST: the Markdown pages as they read on a repository browser
myst_heading_anchors = 4
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]

# --- API reference
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"          # numpydoc's Parameters sections give the types, shapes and units
autodoc_mock_imports: list[str] = []


def _documented_modules() -> set[str]:
    """The modules that have a page of their own: every name in api/index.rst's autosummary lists."""
    text = (Path(__file__).parent / "api" / "index.rst").read_text(encoding="utf-8")
    return {ln.strip() for ln in text.splitlines() if ln.startswith("   notchfit")}


DOCUMENTED_MODULES = _documented_modules()


def _skip_reexports(app, what, name, obj, skip, options):
    """An object is described on one page only: that of the closest documented module it lives in (its own
    module, or the package above it that re-exports it); other packages that re-export it skip it."""
    if what != "module":
        return skip
    here = app.env.temp_data.get("autodoc:module")
    home = getattr(obj, "__module__", None)
    if not here or not isinstance(home, str):
        return skip
    parts = home.split(".")
    page = next((".".join(parts[:k]) for k in range(len(parts), 0, -1) if ".".join(parts[:k]) in DOCUMENTED_MODULES),
                None)
    if page is not None and page != here:
        return True
    return skip


numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()
numpydoc_xref_param_type = False

# --- cross-references: nitpicky (-n) for this project's names; the third-party types that the
# docstrings name (no intersphinx: the build stays offline) are listed here
nitpick_ignore_regex = [
    ("py:.*", r"(np|numpy|pd|pandas|scipy|cv2|matplotlib|mpl|plt|numba|dask|concurrent|multiprocessing|"
              r"argparse|pathlib|os|collections|typing|datetime|threading|subprocess|jinja2|tqdm)(\..*)?"),
    ("py:.*", r"(Path|ndarray|DataFrame|Series|Figure|Axes|Callable|Iterable|Sequence|Mapping|Any|"
              r"PathLike|TextIO|ArgumentParser|Namespace|Generator|Iterator)"),
]

# --- HTML: the theme scientific Python projects use
html_theme = "pydata_sphinx_theme"
html_title = f"notchfit {release}"
html_static_path = ["_static"]
html_css_files = ["notchfit.css"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
    "secondary_sidebar_items": ["page-toc"],
}
html_sidebars = {"index": [], "changelog": []}
html_show_sourcelink = False
html_copy_source = False

# --- the gallery: small executed examples, each drawing its figure
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "plot_gallery": os.environ.get("NOTCHFIT_DOCS_PLOT", "True"),
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "reset_modules": ("matplotlib",),
    "show_memory": False,
    "min_reported_time": 1,
    "write_computation_times": False,   # its page loads scripts from the network; the build log has the times
}


def setup(app):
    app.connect("autodoc-skip-member", _skip_reexports)
