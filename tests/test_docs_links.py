"""The offline link check of the documentation site (docs/check_links.py) finds what is broken."""
from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _checker():
    spec = importlib.util.spec_from_file_location("check_links", ROOT / "docs" / "check_links.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_broken_files_and_anchors_are_found(tmp_path):
    (tmp_path / "api").mkdir()
    (tmp_path / "_static").mkdir()
    (tmp_path / "index.html").write_text(
        '<h1 id="top">x</h1><a href="api/mod.html#f">ok</a><a href="api/">folder</a>'
        '<a href="#top">self</a><a href="https://example.org/x">external</a>'
        '<img src="_static/logo.png"><a href="api/gone.html">gone</a><a href="api/mod.html#nope">bad anchor</a>')
    (tmp_path / "api" / "mod.html").write_text('<dt id="f">f</dt><a href="../index.html#top">up</a>')
    (tmp_path / "api" / "index.html").write_text('<a href="../index.html">home</a>')
    (tmp_path / "_static" / "logo.png").write_bytes(b"png")
    (tmp_path / "_static" / "macros.html").write_text('<a href="{{ pathto(x) }}">template</a>')
    broken, external = _checker().broken_links(tmp_path)
    assert broken == ["index.html: api/gone.html: no such file", "index.html: api/mod.html#nope: no anchor #nope"]
    assert external == 1
    assert _checker().main([str(tmp_path)]) == 1
    (tmp_path / "index.html").write_text('<h1 id="top">x</h1><a href="api/mod.html#f">ok</a>')
    assert _checker().main([str(tmp_path)]) == 0
