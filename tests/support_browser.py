"""A page of ``turbinefit view`` in a real headless browser: Debian's Chromium driven by
playwright (``pip install playwright``; never ``playwright install``, which downloads a
browser build: the system's is used), for ``tests/view/test_browser.py`` and
``benchmarks/bench_view.py``.

Chromium runs with the flags of a machine whose network is closed (no background
networking, updates, sync or QUIC) and a fresh profile in a temporary folder.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: Chromium's flags (``--headless`` and ``--user-data-dir`` are added per launch).
CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update",
                  "--disable-sync")
#: The window the page is drawn in [px].
VIEWPORT = {"width": 1400, "height": 860}


def chromium_path() -> str | None:
    """Chromium's executable (``TURBINEFIT_CHROMIUM``, else ``chromium`` on the PATH, else
    ``/usr/bin/chromium``), or None."""
    for cand in (os.environ.get("TURBINEFIT_CHROMIUM"), shutil.which("chromium"),
                 "/usr/bin/chromium"):
        if cand and Path(cand).is_file() and os.access(cand, os.X_OK):
            return cand
    return None


def why_no_browser() -> str | None:
    """Why a page cannot be opened here (None: it can)."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install playwright, or '.[dev]')"
    if chromium_path() is None:
        return "no Chromium (apt-get install chromium, or set TURBINEFIT_CHROMIUM)"
    return None


@dataclass
class OpenedPage:
    """A page opened in the browser, with what it said while loading.

    Attributes:
        page: playwright's page.
        seconds: wall time from the request to the page's ready flag.
        ready_ms: the page's own time to ready since navigation began.
        errors: console errors and uncaught exceptions.
        requests: every URL the page asked for.
    """

    page: Any
    seconds: float
    ready_ms: float
    errors: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)


@contextmanager
def opened(path: Path, timeout_s: float = 60.0) -> Iterator[OpenedPage]:
    """Open the page ``path`` in headless Chromium; wait until it says it is ready (its
    ``<html data-ready>``: drawn, or an error shown)."""
    from playwright.sync_api import sync_playwright

    exe = chromium_path()
    assert exe is not None, why_no_browser()
    with tempfile.TemporaryDirectory(prefix="turbinefit-chromium-") as profile, \
            sync_playwright() as p:
        ctx = p.chromium.launch_persistent_context(
            profile, executable_path=exe, headless=True, args=["--headless", *CHROMIUM_FLAGS],
            viewport=VIEWPORT)
        try:
            page = ctx.new_page()
            errors: list[str] = []
            requests: list[str] = []
            page.on("console", lambda m: errors.append(f"console: {m.text}")
                    if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
            page.on("request", lambda r: requests.append(r.url))
            t0 = time.perf_counter()
            page.goto(path.resolve().as_uri())
            page.wait_for_selector("html[data-ready]", state="attached", timeout=timeout_s * 1000)
            seconds = time.perf_counter() - t0
            ready_ms = float(page.evaluate("() => window.turbinefitView.readyMs || -1"))
            yield OpenedPage(page, seconds, ready_ms, errors, requests)
        finally:
            ctx.close()
