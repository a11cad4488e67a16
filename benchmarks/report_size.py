"""What a researcher gets from the demo: the output's size on disk, the report's bytes and height.

Usage::

    notchfit demo --out /tmp/demo            # or any output of the pipeline
    python benchmarks/report_size.py /tmp/demo

Prints the size of every top-level folder and of the whole output (as
``du`` counts it), the size of ``report.html`` in bytes, and its height in
CSS pixels laid out 1280 px wide by a headless Chromium (``chromium`` on
PATH; without it the height is skipped): a copy of the page that writes
``document.documentElement.scrollHeight`` into its title is loaded with
``--dump-dom``. One screen is 1080 px.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

SCREEN_PX = 1080


def disk_usage(path: Path) -> int:
    """Bytes of the files under ``path`` (apparent sizes)."""
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.is_dir() else path.stat().st_size


def page_height(report: Path, *, width: int = 1280, timeout: float = 120.0) -> int | None:
    """The report's layout height [px] at ``width``, or None without Chromium."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if exe is None:
        return None
    probe = report.with_name(".height-probe.html")
    probe.write_text(report.read_text() + "<script>document.title='H='+document.documentElement.scrollHeight"
                     "</script>")
    try:
        with tempfile.TemporaryDirectory() as profile:
            dom = subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                                  "--disable-component-update", "--disable-sync", "--no-first-run",
                                  f"--user-data-dir={profile}", f"--window-size={width},{SCREEN_PX}",
                                  "--virtual-time-budget=5000", "--dump-dom", probe.resolve().as_uri()],
                                 capture_output=True, text=True, timeout=timeout).stdout
    finally:
        probe.unlink(missing_ok=True)
    m = re.search(r"<title>H=(\d+)", dom)
    return int(m.group(1)) if m else None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path, help="a demo's --out folder (or a results folder)")
    args = ap.parse_args(argv)
    out = args.out
    for sub in sorted(p for p in out.iterdir() if p.is_dir()):
        print(f"{sub.name + '/':12s} {disk_usage(sub) / 1e6:8.1f} MB")
    print(f"{'total':12s} {disk_usage(out) / 1e6:8.1f} MB")
    reports = sorted(out.rglob("report.html"))
    if not reports:
        print("no report.html")
        return 1
    for r in reports:
        h = page_height(r)
        screens = f"{h} px = {h / SCREEN_PX:.1f} screens of {SCREEN_PX} px" if h else "height: no chromium"
        print(f"{r.relative_to(out)}: {r.stat().st_size:,} bytes; {screens}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
