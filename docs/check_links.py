"""Check the built site's internal links offline: every relative link and every ``#anchor`` resolves.

``sphinx -b linkcheck`` checks links by fetching them (online); this reads
the HTML that ``sphinx -b html`` wrote and checks, without a network, that
each ``href``/``src`` without a scheme points to a file of the site and that
its fragment is an ``id`` in that file. External links (``http:``,
``https:``, ``mailto:``) are listed by count and not followed.

Usage: ``python docs/check_links.py docs/_build/html`` (exit 1 and one line
per broken link when any is broken).
"""

from __future__ import annotations

import sys
from collections import defaultdict
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit


#: Folders of the built site that hold no pages (the theme's template fragments live in _static).
SKIP = {"_static", "_sources", "_images", "_downloads"}


class _Page(HTMLParser):
    """The ids and the links (tag attribute values) of one HTML page."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        for key, value in attrs:
            if key in ("id", "name") and value:
                self.ids.add(value)
            elif value and ((key == "href" and tag in ("a", "link", "area")) or
                            (key == "src" and tag in ("img", "script", "iframe", "source"))):
                self.links.append(value)


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8", errors="replace"))
    return page


def broken_links(site: Path) -> tuple[list[str], int]:
    """``(["page: link: why", ...], number of external links)`` for the HTML site in ``site``."""
    site = site.resolve()
    pages = {p: _parse(p) for p in site.rglob("*.html") if p.relative_to(site).parts[0] not in SKIP}
    broken, external = [], 0
    seen = defaultdict(set)
    for path, page in pages.items():
        for link in page.links:
            parts = urlsplit(link)
            if parts.scheme or link.startswith("//"):
                external += 1
                continue
            target = path if not parts.path else (path.parent / unquote(parts.path)).resolve()
            if target.is_dir():
                target = target / "index.html"
            where = f"{path.relative_to(site)}: {link}"
            if not target.is_relative_to(site) or not target.exists():
                broken.append(f"{where}: no such file")
                continue
            fragment = unquote(parts.fragment)
            if fragment and target.suffix == ".html" and link not in seen[path]:
                seen[path].add(link)
                ids = pages[target].ids if target in pages else _parse(target).ids
                if fragment not in ids:
                    broken.append(f"{where}: no anchor #{fragment}")
    return broken, external


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    site = Path(argv[0] if argv else "docs/_build/html")
    if not (site / "index.html").is_file():
        print(f"{site}: no index.html (build the site first)", file=sys.stderr)
        return 2
    broken, external = broken_links(site)
    for line in broken:
        print(f"broken link: {line}")
    n_pages = sum(1 for p in site.rglob("*.html") if p.relative_to(site).parts[0] not in SKIP)
    print(f"links: {n_pages} pages checked, {len(broken)} broken internal links, "
          f"{external} external links not followed")
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
