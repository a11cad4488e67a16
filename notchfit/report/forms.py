"""The report's typed forms: what a page shows, as frozen dataclasses, before any HTML.

Sections (:mod:`notchfit.report.sections`, :mod:`notchfit.report.diagnosis`)
build these from the results read through :mod:`notchfit.io`; the Jinja2
templates in ``templates/`` (autoescaped) lay them out. Text fields are plain
text: ``**bold**`` and ```code``` are the only markup, turned into HTML by the
templates' ``rich`` filter after escaping.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

__all__ = ["Details", "Figure", "Glance", "Heading", "Link", "NotAvailable", "Page", "Para", "Section", "Table",
           "Block"]


@dataclass(frozen=True)
class Link:
    """A relative link to a file beside the report (a table cell or a list item)."""

    href: str
    text: str


@dataclass(frozen=True)
class Para:
    """A paragraph; ``style`` is one of "", "params", "note", "conv" (the page's boxes)."""

    kind: ClassVar[str] = "para"
    text: str
    style: str = ""
    links: tuple[Link, ...] = ()


@dataclass(frozen=True)
class Heading:
    kind: ClassVar[str] = "heading"
    text: str


@dataclass(frozen=True)
class NotAvailable:
    """The line a section shows when its input is absent: "not available: <why>"."""

    kind: ClassVar[str] = "na"
    why: str


@dataclass(frozen=True)
class Table:
    """A table of formatted cells (str or :class:`Link`); ``named`` marks rows to highlight."""

    kind: ClassVar[str] = "table"
    columns: tuple[str, ...]
    rows: tuple[tuple, ...]
    text_columns: tuple[str, ...] = ()
    named: tuple[bool, ...] = ()

    @classmethod
    def of(cls, rows: list[dict], *, text_columns=(), named=None) -> Table | None:
        """From dicts of one layout (None for no rows); ``named(row) -> bool`` marks rows."""
        if not rows:
            return None
        cols = tuple(rows[0])
        return cls(cols, tuple(tuple(r.get(c, "") for c in cols) for r in rows), tuple(text_columns),
                   tuple(bool(named(r)) for r in rows) if named else ())


@dataclass(frozen=True)
class Figure:
    """An embedded image (``data:`` URI) shown 1:1 at ``width``×``height`` px, with its caption."""

    kind: ClassVar[str] = "figure"
    uri: str
    caption: str
    alt: str
    width: int | None = None
    height: int | None = None


@dataclass(frozen=True)
class Details:
    """Text folded away behind a summary line."""

    kind: ClassVar[str] = "details"
    summary: str
    text: str


@dataclass(frozen=True)
class Glance:
    """The first section's table: ``(label, text)`` rows, text blocks under it."""

    kind: ClassVar[str] = "glance"
    rows: tuple[tuple[str, str], ...]


Block = Para | Heading | NotAvailable | Table | Figure | Details | Glance


@dataclass(frozen=True)
class Section:
    key: str
    title: str
    blocks: tuple = ()


@dataclass(frozen=True)
class Page:
    """The whole report: title, the header line, the sections in order, and the study's units."""

    title: str
    version: str
    created: str
    study: str
    sections: tuple[Section, ...]
    angles: bool = False
    extra: dict = field(default_factory=dict)
