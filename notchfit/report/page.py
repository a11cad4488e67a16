"""The report's page pieces: numbers with sensible digits, embedded figures, relative links, the templates.

Shared by :mod:`notchfit.report` and its sections; no notchfit analysis here.
The page is laid out by the Jinja2 templates in ``templates/`` with
autoescaping on: every text a section gives is escaped, and ``**bold**`` and
```code``` are the only markup it may carry (:func:`rich`).
"""

from __future__ import annotations

import base64
import html as _html
import io as _pyio
import math
import os
import re
from pathlib import Path

import jinja2
from markupsafe import Markup

from .forms import Figure, Link, Page

__all__ = ["figure", "image", "link", "newton", "num", "pct", "rel", "render_page", "rich", "TEMPLATES"]

#: The folder of the report's templates and style sheet (package data).
TEMPLATES = Path(__file__).parent / "templates"


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def num(v, digits: int = 3, *, sign: bool = False, trim: bool = False) -> str:
    """``v`` with ``digits`` significant digits ("–" for none/NaN).

    Fixed-point between 1e-4 and 1e5, else ``m×10ⁿ``; ``sign`` writes ``+``
    before positive values (signed quantities such as ``a`` and ``b``);
    ``trim`` drops trailing zeros (parameter values given, not measured:
    0.01, not 0.0100).
    """
    try:
        v = float(v)
    except (TypeError, ValueError):
        return "–" if v is None else str(v)
    if not math.isfinite(v):
        return "–"
    if v == 0:
        return "0"
    plus = "+" if sign else ""
    mag = math.floor(math.log10(abs(v)))
    if -4 <= mag < 5:
        text = f"{v:{plus}.{max(0, digits - 1 - mag)}f}"
        return text.rstrip("0").rstrip(".") if trim and "." in text else text
    mant, exp = f"{v:{plus}.{digits - 1}e}".split("e")
    if trim and "." in mant:
        mant = mant.rstrip("0").rstrip(".")
    return f"{mant}×10{str(int(exp)).translate(_SUPERSCRIPT)}"


def pct(v, digits: int = 2) -> str:
    """A percentage with ``digits`` significant digits (at least whole percent)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        return "–"
    return "–" if not math.isfinite(v) else f"{v:.{max(0, digits - 1 - math.floor(math.log10(max(abs(v), 1))))}f} %"


def rel(path, root) -> str:
    """``path`` relative to the report's folder ``root`` (POSIX separators)."""
    try:
        return Path(os.path.relpath(Path(path).resolve(), Path(root).resolve())).as_posix()
    except ValueError:                                    # another drive (Windows)
        return Path(path).as_posix()


def newton(v, decimals: int = 2) -> str:
    """A tension [N] with the digits the load cell resolves (``decimals`` after the point) and at most
    three significant digits: 0.0058 N at a 0.1 mN resolution, not "0.01 N"; 27.7 N, not 27.6843."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        return "–"
    if not math.isfinite(v):
        return "–"
    if v == 0:
        return "0"
    mag = math.floor(math.log10(abs(v)))
    return f"{v:.{max(0, min(decimals, 2 - mag))}f}"


def link(path, root, text=None) -> Link:
    """A relative link to a file beside the report."""
    r = rel(path, root)
    return Link(r, text if text is not None else r)


def image(data: bytes, mime: str, caption: str, alt: str, size=None) -> Figure:
    """An embedded image with its one-sentence caption; ``size`` = (w, h) px shows it 1:1."""
    uri = f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"
    return Figure(uri, caption, alt, *(size or (None, None)))


def figure(fig, caption: str, alt: str, *, dpi: int = 100) -> Figure:
    """A matplotlib figure embedded as PNG at ``dpi`` (one figure pixel = one screen pixel at 100 %)."""
    buf = _pyio.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    w, h = (int(round(x * dpi)) for x in fig.get_size_inches())
    return image(buf.getvalue(), "image/png", caption, alt, (w, h))


_BOLD = re.compile(r"\*\*(.+?)\*\*")
_CODE = re.compile(r"`([^`]+)`")


def rich(text) -> Markup:
    """``text`` escaped, then ``**bold**`` → ``<b>`` and ```code``` → ``<code>`` (the only markup a section's
    text may carry)."""
    html = _html.escape(str(text), quote=False)           # text, not attributes: quotes stay as typed
    html = _CODE.sub(r"<code>\1</code>", html)
    return Markup(_BOLD.sub(r"<b>\1</b>", html))


def _environment() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters["rich"] = rich
    env.tests["link"] = lambda x: isinstance(x, Link)
    return env


_ENV = None


def render_page(page: Page) -> str:
    """The report's HTML from its typed form (``templates/report.html.j2``)."""
    global _ENV
    if _ENV is None:
        _ENV = _environment()
    return _ENV.get_template("report.html.j2").render(page=page)
