"""Where the browser tests find Chromium, and what they do without one.

A developer without a browser gets a skip that says why; CI must have one
(``.ci/run`` installs Debian's ``chromium`` and sets ``NOTCHFIT_REQUIRE_BROWSER=1``),
so there a missing browser fails the test instead of skipping it silently.
"""

from __future__ import annotations

import os
import shutil

import pytest


def chromium_path() -> str | None:
    """The Chromium executable: ``$NOTCHFIT_CHROMIUM``, Debian's, or the first on PATH."""
    for path in (os.environ.get("NOTCHFIT_CHROMIUM"), "/usr/bin/chromium",
                 *(shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome"))):
        if path and os.path.isfile(path):
            return path
    return None


def no_browser(reason: str):
    """Skip with ``reason``, or fail where a browser is required (CI)."""
    if os.environ.get("NOTCHFIT_REQUIRE_BROWSER") == "1":
        pytest.fail(f"a browser is required here (NOTCHFIT_REQUIRE_BROWSER=1) but {reason}")
    pytest.skip(reason)
