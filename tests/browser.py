"""A real headless Chromium for the tests of the HTML pages (replay, report).

The browser is the system's Chromium (Debian's ``chromium`` package, which ``.ci/run``
installs when it is absent), driven by Playwright for Python; Playwright's own browser
download is never used. ``CRLBSWARM_CHROMIUM`` names another executable.

Where no Chromium is found the browser tests are skipped with the reason, except when the
environment variable ``CRLBSWARM_REQUIRE_BROWSER=1`` is set (``.ci/run`` sets it): then
they fail, so that CI never passes without having run them.

Use::

    from browser import open_page

    def test_page(tmp_path):
        with open_page(tmp_path / "page.html") as page:
            ...  # page.console_errors lists the console errors and page errors so far
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

#: Flags for a headless Chromium on a machine with a closed network, run as any user.
CHROMIUM_ARGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)


def chromium_executable() -> str | None:
    """The Chromium to drive: ``$CRLBSWARM_CHROMIUM``, else the first on ``PATH``."""
    given = os.environ.get("CRLBSWARM_CHROMIUM")
    if given:
        return given
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def _need_browser() -> str:
    exe = chromium_executable()
    reason = "no Chromium executable found (install Debian's chromium, or set CRLBSWARM_CHROMIUM)"
    if exe is None:
        if os.environ.get("CRLBSWARM_REQUIRE_BROWSER") == "1":
            pytest.fail(reason)
        pytest.skip(reason)
    return exe


@contextmanager
def open_page(path: Path | str, width: int = 1280, height: int = 860) -> Iterator[Any]:
    """Open the local HTML file ``path`` in a fresh headless Chromium page.

    The page has an attribute ``console_errors``: the text of every console message of type
    ``error`` and of every uncaught page error, in order. The browser is closed on exit.
    Network requests other than ``file:`` and ``data:`` are aborted (the pages must work
    offline) and recorded in ``page.external_requests``.
    """
    exe = _need_browser()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=list(CHROMIUM_ARGS))
        try:
            page = browser.new_page(viewport={"width": width, "height": height})
            errors: list[str] = []
            external: list[str] = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))

            def _route(route: Any) -> None:
                url = route.request.url
                if url.startswith(("file:", "data:", "blob:")):
                    route.continue_()
                else:
                    external.append(url)
                    route.abort()

            page.route("**/*", _route)
            page.console_errors = errors
            page.external_requests = external
            page.goto(Path(path).resolve().as_uri())
            yield page
        finally:
            browser.close()
