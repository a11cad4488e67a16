"""The report's page pieces: numbers with sensible digits, tables, embedded figures, relative links.

Shared by :mod:`notchfit.report` and its sections; no notchfit analysis here.
"""

from __future__ import annotations

import base64
import html
import io as _pyio
import math
import os
from pathlib import Path

__all__ = ["CSS", "esc", "figure_html", "image_html", "link", "na", "num", "pct", "rel", "table"]

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1080px;
margin:1.2em auto;padding:0 1em;color:#222;line-height:1.4;font-size:15px}
h1{font-size:1.5em;margin:.2em 0}h2{font-size:1.25em;margin:1.4em 0 .4em;border-bottom:1px solid #bbb}
h3{font-size:1.05em;margin:1em 0 .3em}
table{border-collapse:collapse;margin:.4em 0;font-size:.9em}
td,th{border:1px solid #ccc;padding:.2em .55em;text-align:right;vertical-align:top}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}td.text,th.text{text-align:left}
table.glance{width:100%;font-size:1em}table.glance th{width:9em;text-align:left;background:#eef3f8}
table.glance td{text-align:left}
.na{color:#a33;font-style:italic}.meta{color:#555;font-size:.85em;margin:.2em 0 .6em}
.note{background:#fff8e1;border-left:4px solid #f0b400;padding:.4em .7em;margin:.6em 0}
.conv{background:#f4f4f4;padding:.4em .7em;font-size:.9em;margin:.6em 0}
.params{background:#eef6ee;border-left:4px solid #4a4;padding:.35em .7em;margin:.5em 0}
figure{margin:.5em 0}figure img{max-width:100%;height:auto}
figcaption{font-size:.9em;color:#333;margin-top:.2em}
tr.named td{background:#e8f5e9;font-weight:600}
nav{font-size:.9em}nav a{margin-right:.9em}
details{margin:.4em 0}summary{cursor:pointer;color:#335}
"""


def esc(x) -> str:
    return html.escape(str(x))


def na(why: str) -> str:
    """The line a section shows when its input is absent."""
    return f'<p class="na">not available: {esc(why)}</p>'


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


def link(path, root, text=None) -> str:
    """A relative link to a file beside the report."""
    r = rel(path, root)
    return f'<a href="{esc(r)}">{esc(text if text is not None else r)}</a>'


def table(rows: list[dict], *, cls: str = "", row_cls=None, text_cols=()) -> str:
    """An HTML table of already formatted cells; ``row_cls(row) -> str`` marks rows."""
    if not rows:
        return ""
    cols = list(rows[0])
    head = "".join(f'<th class="text">{esc(c)}</th>' if c in text_cols else f"<th>{esc(c)}</th>" for c in cols)
    body = []
    for r in rows:
        rc = row_cls(r) if row_cls else ""
        cells = "".join(f'<td class="text">{esc(r.get(c, ""))}</td>' if c in text_cols
                        else f"<td>{esc(r.get(c, ''))}</td>" for c in cols)
        body.append(f'<tr class="{rc}">{cells}</tr>' if rc else f"<tr>{cells}</tr>")
    c = f' class="{cls}"' if cls else ""
    return f"<table{c}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def image_html(data: bytes, mime: str, caption: str, alt: str, size=None) -> str:
    """An embedded image with its one-sentence caption; ``size`` = (w, h) px shows it 1:1."""
    b64 = base64.b64encode(data).decode("ascii")
    wh = f' width="{size[0]}" height="{size[1]}"' if size else ""
    return (f'<figure><img alt="{esc(alt)}"{wh} src="data:{mime};base64,{b64}">'
            f"<figcaption>{caption}</figcaption></figure>")


def figure_html(fig, caption: str, alt: str, *, dpi: int = 100) -> str:
    """A matplotlib figure embedded as PNG at ``dpi`` (one figure pixel = one screen pixel at 100 %)."""
    buf = _pyio.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    w, h = (int(round(x * dpi)) for x in fig.get_size_inches())
    return image_html(buf.getvalue(), "image/png", caption, alt, (w, h))
