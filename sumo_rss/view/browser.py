"""A headless Chromium for the viewer's tests, benchmark and screenshots: Debian's ``chromium`` driven by playwright
(the ``dev`` extra). Playwright's own browser downloads are never used."""
from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

# Flags that work headless as root on a machine without GPU or network (playwright adds --headless and a fresh
# --user-data-dir).
CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync")
READY = "document.body.dataset.ready === 'true'"  # the viewer has drawn its first frame
STATES_READY = "document.body.dataset.states === 'ready'"  # ... and read the episodes' states (its charts' data)


def chromium_path() -> str | None:
    """``$SUMO_RSS_CHROMIUM``, else Debian's chromium on the PATH; None where there is none."""
    named = os.environ.get("SUMO_RSS_CHROMIUM")
    if named:
        return named if Path(named).is_file() else None
    return next((found for name in ("chromium", "chromium-browser") if (found := shutil.which(name))), None)


def missing_browser() -> str | None:
    """Why no browser can be started here (None: one can)."""
    if chromium_path() is None:
        return "no chromium here (Debian: apt-get install -y chromium; .ci/run installs it; or set SUMO_RSS_CHROMIUM)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install -e '.[dev]')"
    return None


@contextmanager
def headless_chromium() -> Iterator[Any]:
    """A playwright ``Browser`` on headless Chromium, closed at the end."""
    from playwright.sync_api import sync_playwright

    reason = missing_browser()
    if reason is not None:
        raise RuntimeError(reason)
    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=chromium_path(), args=list(CHROMIUM_FLAGS))
        try:
            yield browser
        finally:
            browser.close()


def open_view(browser: Any, page_file: Path, width: int = 1400, height: int = 850, timeout_s: float = 60.0,
              wait_for: str = STATES_READY) -> Any:
    """A new page showing ``page_file`` (a view.html), once ``wait_for`` holds (by default: everything is read);
    its console errors and uncaught exceptions are collected in ``page.errors``."""
    page = browser.new_page(viewport={"width": width, "height": height})
    page.errors = []
    page.on("console", lambda message: page.errors.append(message.text) if message.type == "error" else None)
    page.on("pageerror", lambda error: page.errors.append(str(error)))
    page.goto(Path(page_file).resolve().as_uri())
    page.wait_for_function(wait_for, timeout=timeout_s * 1000)
    return page
